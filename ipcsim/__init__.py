"""ipcsim: Incremental Potential Contact simulation driven by scene files."""

__version__ = "0.1.0"
