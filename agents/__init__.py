"""Policies for slide-gym environments: planner-driven experts and learned agents (to come)."""
