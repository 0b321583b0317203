"""Benchmarks run by ``slide-gym bench``; the documentation's "Benchmarks" page comes from here.

- :mod:`slide_gym.bench.env`: environment throughput (``bench env``).
- :mod:`slide_gym.bench.plan`: the planners' success rate against time (``bench plan``).
- :mod:`slide_gym.bench.execute`: the expert's full episodes (``bench execute``).

The last two run their cases with :mod:`slide_gym.jobs`. The modules import :mod:`agents`
only inside functions, so ``import slide_gym`` does not import it (``agents`` builds on
``slide_gym``'s world, environments and planners).
"""
