"""Development tooling of attica: golden vectors, cross-CPU runs, footprint, instruction counts, benchmarks.

Not part of the installed package (``pip install`` ships only ``host/attica``): these modules build the
firmware for emulated CPUs, run test programs under QEMU and valgrind, and fetch the peers' published
sources. They are reached through the make targets (``make cross``, ``make firmware``, ``make
footprint``, ``make cycles``, ``make bench``, which put ``tools/`` on ``PYTHONPATH``) and imported by
the tests (tests/conftest.py does the same).

- :mod:`attica_dev.golden`: the golden-vector runner tests/c/att_golden.c, its table files, inputs and
  the reference outputs;
- :mod:`attica_dev.cross`: every CPU target (Cortex-M under QEMU, aarch64/riscv64 under qemu-user,
  x86-64) and the bit-exact comparison on each;
- :mod:`attica_dev.footprint`: size, stack and instructions per update on the Cortex-M targets;
- :mod:`attica_dev.bench`: host timing and x86-64 callgrind counts.
"""
