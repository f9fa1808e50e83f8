"""benchmarks/plugin_profile.py's cache model: callgrind's caches are the machine's, read from
sysfs (a fake folder here), and a machine that does not describe them gets an error naming
what is missing."""

from __future__ import annotations

from pathlib import Path

import pytest
from benchmark_scripts import script


def _cache(folder: Path, index: int, level: int, kind: str, size: str, ways: int) -> None:
    d = folder / f"index{index}"
    d.mkdir()
    for name, value in {
        "level": level,
        "type": kind,
        "size": size,
        "ways_of_associativity": ways,
        "coherency_line_size": 64,
    }.items():
        (d / name).write_text(f"{value}\n")


def test_the_simulated_caches_are_the_ones_sysfs_describes(tmp_path: Path) -> None:
    _cache(tmp_path, 0, 1, "Data", "48K", 12)
    _cache(tmp_path, 1, 1, "Instruction", "32K", 8)
    _cache(tmp_path, 2, 2, "Unified", "2M", 16)
    _cache(tmp_path, 3, 3, "Unified", "32768K", 16)
    assert script("plugin_profile").cache_sim(tmp_path) == [
        "--cache-sim=yes",
        "--D1=49152,12,64",
        "--I1=32768,8,64",
        "--LL=2097152,16,64",
    ]


def test_a_machine_without_a_second_level_is_told_what_is_missing(tmp_path: Path) -> None:
    _cache(tmp_path, 0, 1, "Data", "32K", 8)
    _cache(tmp_path, 1, 1, "Instruction", "32K", 8)
    with pytest.raises(RuntimeError, match="level 2 Unified"):
        script("plugin_profile").cache_sim(tmp_path)
