"""armgen: redundant-arm kinematics to verified embedded C, and trajectory planning."""

__version__ = "0.1.0"
