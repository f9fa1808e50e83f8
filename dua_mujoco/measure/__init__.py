"""Measuring: a monitored run against MuJoCo's contacts (misses, warning time, bound checks) and
its report."""
