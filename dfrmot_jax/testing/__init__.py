"""Test tools, kept apart from the product: the NumPy oracle (``reference``), tracker-vs-oracle
comparison (``parity``), random settings (``settings``), metric test outputs (``metric_edits``),
the ``trackeval`` adapter (``trackeval_adapter``). Nothing in the package imports them."""

from .settings import random_options, random_params, random_settings

__all__ = ["random_options", "random_params", "random_settings"]
