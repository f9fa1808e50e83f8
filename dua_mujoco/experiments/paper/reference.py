"""The paper's published numbers (Hayward et al. 1995, Tables 1 to 3), printed beside ours."""

from __future__ import annotations

__all__ = [
    "PAPER_N",
    "PAPER_TABLE1",
    "PAPER_TABLE2_DT",
    "PAPER_TABLE2_DUA",
    "PAPER_TABLE2_SA",
    "PAPER_TABLE3",
    "PAPER_TABLE3_OVERALL",
]

PAPER_N: tuple[int, ...] = (5, 10, 15, 20, 30, 40)
"""Sphere counts of the paper's Tables 1 and 2."""

PAPER_TABLE1: dict[str, tuple[float, ...]] = {
    "DUA": (12.01, 18.74, 22.42, 26.65, 31.14, 39.69),
    "SA": (29.53, 135.133, 323.90, 607.45, 1543.02, 3294.18),
}
"""Paper Table 1, "CPU cycles" per iteration (in fact 1/60 s ticks: 60 x Table 2's Delta t)."""

PAPER_TABLE2_DT: dict[str, tuple[float, ...]] = {
    "DUA": (0.2, 0.31, 0.37, 0.44, 0.52, 0.66),
    "SA": (0.48, 2.23, 5.33, 10.12, 25.31, 53.75),
}
"""Paper Table 2, Delta t per iteration (seconds on a SPARC 470, Common Lisp)."""

PAPER_TABLE2_DUA: dict[int, tuple[int, ...]] = {
    25: (0, 52, 96, 124, 164, 196),
    35: (0, 75, 133, 174, 226, 270),
    50: (0, 104, 189, 248, 319, 379),
    65: (0, 134, 246, 323, 410, 485),
    75: (0, 153, 284, 370, 471, 557),
}
"""Paper Table 2, DUA false alarms by iteration count (repetitive alarms *not* filtered)."""

PAPER_TABLE2_SA: dict[int, tuple[tuple[int, int], ...]] = {
    25: ((0, 0), (88, 102), (496, 1203), (897, 3581), (2193, 8317), (3988, 15489)),
    35: ((0, 0), (109, 125), (655, 1516), (1144, 4955), (2822, 11462), (5118, 21593)),
    50: ((0, 0), (127, 146), (914, 1944), (1538, 6937), (3746, 16076), (6717, 30649)),
    65: ((0, 0), (153, 172), (1199, 2398), (1988, 8909), (4763, 20822), (8539, 39892)),
    75: ((0, 0), (177, 196), (1368, 2671), (2315, 10168), (5433, 23927), (9668, 45958)),
}
"""Paper Table 2, SA(tau) false alarms: (repetitive counted once, all alarms)."""

PAPER_TABLE3: dict[str, dict[str, tuple[float, ...]]] = {
    "iterations": {"n": (25, 50, 75, 100, 150, 200, 250)},
    "dua_sat": {
        "mean": (63.6, 64.2, 67.87, 70.9, 68.73, 68.4, 64.56),
        "std": (27.29, 19.58, 19.30, 19.61, 18.46, 16.61, 20.94),
    },
    "sad_sat": {
        "mean": (16.8, 15.4, 19.73, 19.4, 21.67, 24.0, 21.6),
        "std": (17.66, 13.98, 10.73, 8.56, 9.25, 8.92, 9.13),
    },
}
"""Paper Table 3, most-urgent-pair agreement in percent at N = 10 (10 sequences each)."""

PAPER_TABLE3_OVERALL: dict[str, tuple[float, float]] = {
    "dua_sat": (66.89, 20.26),
    "sad_sat": (19.8, 11.18),
}
"""Paper Table 3, overall (mean, standard deviation) in percent."""
