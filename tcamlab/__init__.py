"""tcamlab: lab pipeline for twisted-and-coiled artificial muscles."""

__version__ = "0.1.0"
