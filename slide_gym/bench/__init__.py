"""Benchmarks run by ``slide-gym bench``; the README's numbers come from here.

- :mod:`slide_gym.bench.env`: environment throughput (``bench env``).
- :mod:`slide_gym.bench.plan`: the planners' success rate against time (``bench plan``).
- :mod:`slide_gym.bench.execute`: the expert's full episodes (``bench execute``).
- :mod:`slide_gym.bench.jobs`: the resumable, parallel JSONL job runner the last two use.

The modules import :mod:`agents` only inside functions: ``slide_gym`` does not depend on it.
"""
