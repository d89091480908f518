"""NanoNav: simulations of learning nanorobots that hunt cancer cells in 3-D tissue."""

__version__ = "0.1.0"
