"""Test tools, kept apart from the product: the NumPy oracle (``reference``), tracker-vs-oracle
comparison (``parity``), random settings (``settings``), metric test outputs (``metric_edits``),
the ``trackeval`` adapter (``trackeval_adapter``), AB3DMOT's tracker in NumPy (``ab3dmot_oracle``)
and line comparison of its output files (``ab3dmot_compare``). Nothing in the package imports them."""

from .settings import random_options, random_params, random_settings

__all__ = ["random_options", "random_params", "random_settings"]
