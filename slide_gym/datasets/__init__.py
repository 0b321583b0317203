"""Demonstration datasets: collect, replay, merge and export (Minari)."""
