"""attica: deterministic attitude estimation firmware, its bit-exact numpy reference and tools.

- :mod:`attica.native`: the C firmware through cffi.
- :mod:`attica.reference`: the numpy float32 mirror, bit for bit.
- :mod:`attica.sim`: deterministic IMU simulator with ground truth.
- :mod:`attica.cli`: the ``attica`` command.
"""

__version__ = "0.1.0"
