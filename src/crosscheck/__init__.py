"""crosscheck: one physics scene, several simulators, honest metrics."""

__version__ = "0.1.0"
