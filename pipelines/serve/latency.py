"""How a browser study reports click-to-reply latencies: median and 95th percentile (nearest rank), in seconds.

One definition for the load client (bench/serve_study.py) and the Chromium-driven tests, so their figures compare.
"""
from __future__ import annotations

import statistics


def latency_stats(values: list[float]) -> dict[str, float] | None:
    """Median and 95th percentile (nearest rank) in seconds; None without values."""
    if not values:
        return None
    ordered = sorted(values)
    return {"n": len(ordered), "median": round(statistics.median(ordered), 3),
            "p95": round(ordered[min(len(ordered) - 1, int(0.95 * len(ordered)))], 3), "max": round(ordered[-1], 3)}
