"""dfrmot_jax: batched JAX DFR-FastMOT tracker for parameter sweeps."""
__version__ = "0.1.0"
