"""The ``dfrmot`` subcommands: their names in the order ``dfrmot --help`` lists them, each one's line
of help, and the module that registers its parser (``add_parser(sub)``). A light module: the parser
lists every command from this table without importing the commands' modules (:mod:`dfrmot_jax.cli`
imports only the named command's parser module, and that command's own module when it runs)."""

from __future__ import annotations

__all__ = ["HELP", "PARSERS", "FAMILIES", "OBJECTIVES"]

#: the tracker families, as the help names them (each family of ``family_configs.CONFIGS``: a test
#: checks that every one is named here); a sweep file picks one with ``[options] family``
FAMILIES = "dfr (DFR-FastMOT, the default) or ab3dmot (AB3DMOT)"
#: what an ``--objective`` may name, as the help says it (``metrics.columns.OBJECTIVE_FIELDS``)
OBJECTIVES = ("HOTA (default), MOTA, IDF1, AssA, DetA, IDSW, Frag (minimised), ...; AB3DMOT's sAMOTA, AMOTA, AMOTP, "
              "ab3dmot_MOTA, ... (sweeps scored with [metrics] ab3dmot; not cross-validated)")

#: command -> its line in ``dfrmot --help`` (each command's ``add_parser`` registers it with this help)
HELP = {
    "track": "track a KITTI split and write one result file per sequence",
    "demo": "a small parameter sweep on a synthetic scene, with its HTML report (no data needed)",
    "eval": "evaluate KITTI tracking result folders (TrackEval's KITTI 2D box HOTA/CLEAR/Identity; AB3DMOT's "
            "sAMOTA/AMOTA with --metrics ab3dmot)",
    "compare": "compare two result folders: per-sequence differences, paired bootstrap intervals over sequences",
    "sweep": "run a sweep file of either tracker family, dfr or ab3dmot (tracking + metrics for every config), "
             "resumable",
    "tune": "tune a sweep file's parameters (either tracker family) with batched Optuna search (+ gradient "
            "refinement)",
    "report": "best configs, baseline, sensitivity and cross-validation of a sweep or tune directory (either "
              "tracker family)",
    "lidar": "simulate LiDAR scans; lift 2D detections to 3D boxes from scans",
}

#: command -> the module (of ``dfrmot_jax.cli``) whose ``add_parser(sub)`` registers it: ``CMD_parser``,
#: which imports nothing heavy (``dfrmot CMD --help`` imports neither the command's module nor what it
#: runs: ``track``'s lists every parameter, option and preset from ``config`` alone); its ``func`` imports
#: the command's own module, ``CMD``, when it runs (``errors.run_later``)
PARSERS = {name: f"{name}_parser" for name in HELP}
