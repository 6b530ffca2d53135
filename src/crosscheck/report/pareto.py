"""The Pareto front of accuracy against cost: the runs no other run beats on both."""

from __future__ import annotations


def front(points: list[tuple[float, float]]) -> list[int]:
    """Indices of the (cost, error) points that no other point beats in both (at least as
    cheap and as accurate, and strictly better in one), ordered by cost."""
    keep = [i for i, (c, e) in enumerate(points)
            if not any((c2 <= c and e2 < e) or (c2 < c and e2 <= e) for c2, e2 in points)]
    return sorted(keep, key=lambda i: points[i])
