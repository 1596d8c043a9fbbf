"""The package version, below every module that records it (specs, stores, the CLI)."""

__version__ = "0.1.0"
