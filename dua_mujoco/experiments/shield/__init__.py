"""The safety shield against its peers (issue 40): episodes of the shield's scenes
(:mod:`dua_mujoco.models.cells`) under a safety layer, what they count (:mod:`.episodes`), the
peers as their sources write them (:mod:`.peers`), and many episodes in parallel with their
table (:mod:`.bench`). The command: ``benchmarks/shield.py``."""
