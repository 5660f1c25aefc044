"""The package version, in a module of its own so that any module can name it without importing the
package root (which imports every subpackage)."""

__version__ = "0.1.0"

#: The version of what a sweep's rows are computed with: bumped whenever a change to the tracker or
#: the scoring changes any row, so that a resumed sweep recomputes the chunks an older version wrote
#: (``sweep.store``: each chunk's ledger record names it; a record without one is version 1).
#: 2 (2026-11-26): the scores' memo names the boxes the lanes of an option group share, and the boxes
#: are scored as their result files print them.
RESULTS_VERSION = 2
