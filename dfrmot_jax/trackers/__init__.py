"""The tracker families' wing: each family in a folder of its own (``dfr/``: DFR-FastMOT, ``ab3dmot/``:
AB3DMOT) behind one protocol (``protocol``), their registry (``registry``: one line per family), and the
rules every family shares (``capacity``: the one capacity policy; ``lanes``: lanes grouped into
compiled calls). A family imports the protocol and the shared pieces, never another family; the
machinery around the families (sweeps, tunes, the report, the command line) asks the registry.
"""

__all__: list[str] = []
