"""Evaluation harness of multisession_mapper (issue 4).

Reads a map directory written by the pipeline (docs/map_format.md) and the simulator's ground
truth (docs/simulator.md) and computes the reference paper's loop-closure table, ATE/RPE with
the definitions of the `evo` tool, scan-level place-recognition precision/recall, the DynamicMap
benchmark's SA/DA/AA/HA, map-size figures and timings. The protocol and every key of
report.json are documented in docs/evaluation.md.
"""

__all__ = ['cli', 'dynamics', 'io', 'loops', 'map_stats', 'neighbors', 'pcd', 'place_recognition',
           'plots', 'report', 'timing', 'trajectory']
