"""The booth's staggered starts split into independent groups of robots
(`paintcell.booth.booth_stagger`): the delays against a brute-force search over every
combination, re-measured on one clock, and a group that cannot be placed refused without
trying the delays of robots that meet nobody."""

from __future__ import annotations

import itertools
import re

import numpy as np
import pytest

from paintcell.booth import booth_stagger
from paintcell.booth.booth import BoothError
from paintcell.booth.booth_stagger import stagger_starts


def _apart(p: np.ndarray, q: np.ndarray, dp: int, dq: int, d_m: float) -> bool:
    """Whether p and q (K, P, 3) keep d_m apart when started dp and dq samples late, each
    holding its first pose before its start and its last after its end (one clock)."""
    idx = np.arange(max(len(p) + dp, len(q) + dq))
    a, b = p[np.clip(idx - dp, 0, len(p) - 1)], q[np.clip(idx - dq, 0, len(q) - 1)]
    return bool(np.linalg.norm(a[:, :, None] - b[:, None], axis=3).min() >= d_m)


def _brute_force(paths: list[np.ndarray], dmax: int, d_m: float) -> list[int] | None:
    """Every delay combination 0..dmax: the feasible one of the shortest cycle, then the least
    sum of delays, then the earliest robots' least (the search's rule); None when none."""
    n, lens = len(paths), np.array([len(p) for p in paths])
    d = np.indices((dmax + 1,) * n).reshape(n, -1).T          # (C, n): every combination
    ok = np.ones(len(d), bool)
    for i, j in itertools.combinations(range(n), 2):
        table = np.array([[_apart(paths[i], paths[j], di, dj, d_m) for dj in range(dmax + 1)]
                          for di in range(dmax + 1)])
        ok &= table[d[:, i], d[:, j]]
    if not ok.any():
        return None
    d = d[ok]
    keys = [(int(c), int(s), tuple(int(x) for x in row))
            for c, s, row in zip((lens + d).max(1), d.sum(1), d, strict=True)]
    return list(min(keys)[2])


def _agrees_with_brute_force(paths: list[np.ndarray], dt: float, d_m: float, dmax: int) -> bool:
    """Whether the brute force finds delays (True) or none (False); either way the search
    agrees: its delays equal the brute force's and keep every pair apart on one clock, or it
    refuses in one line."""
    want = _brute_force(paths, dmax, d_m)
    if want is None:
        with pytest.raises(BoothError, match="arm comes closer"):
            stagger_starts(paths, dt, d_m)
        return False
    got = stagger_starts(paths, dt, d_m)
    assert got == want
    assert all(_apart(paths[i], paths[j], got[i], got[j], d_m)
               for i in range(len(paths)) for j in range(i))
    return True


def test_stagger_in_groups_is_the_brute_force_optimum(monkeypatch):
    """Five robots in two clusters 100 m apart plus one alone, shuffled so the groups interleave
    in robot order: the grouped search's delays equal the brute force's on every random case
    (feasible and not), and keep the clearance on one clock. The second cluster's group ends
    sooner on some cases and must then take its least delays under the longer cycle: so in the
    first case, where robot 0 (4 samples) crosses the point robot 1 (20 samples) holds in its
    samples 1-6: robot 0 waiting 5 samples ends the pair soonest (20), but with a lone robot of
    30 samples robot 1 waiting 2 costs less."""
    monkeypatch.setattr(booth_stagger, "STAGGER_MAX_S", 1.5)     # 7 delays of 0.25 s
    dt, d_m, dmax = 0.25, 0.5, 6

    def at(*pts: tuple[float, ...]) -> np.ndarray:
        return np.array(pts, float)[:, None, :]

    z, f0, f1 = (0.0, 0.0, 0.0), (10.0, 0.0, 0.0), (-10.0, 0.0, 0.0)
    pair = [at(f0, f0, z, f0), at(f1, *[z] * 6, *[f1] * 13)]
    assert stagger_starts(pair, dt, d_m) == _brute_force(pair, dmax, d_m) == [5, 0]
    lone = at(*[(100.0, 0.0, 0.0)] * 30)
    assert stagger_starts([*pair, lone], dt, d_m) == _brute_force([*pair, lone], dmax, d_m) \
        == [0, 2, 0]
    rng = np.random.default_rng(3)
    solved = refused = 0
    for _ in range(30):
        paths = []
        for cluster, n in ((0.0, 2), (100.0, 2), (200.0, 1)):
            for _ in range(n):
                k = int(rng.integers(3, 14 if n == 2 else 20))
                walk = np.cumsum(rng.normal(0, 0.25, (k, 2, 3)), axis=0)
                paths.append(walk + rng.normal(0, 0.4, 3) + [cluster, 0.0, 0.0])
        order = rng.permutation(5)
        paths = [paths[k] for k in order]
        if _agrees_with_brute_force(paths, dt, d_m, dmax):
            solved += 1
        else:
            refused += 1
    assert solved >= 10 and refused >= 3


def test_robots_that_meet_nobody_do_not_multiply_the_search(monkeypatch):
    """Three robots that meet nobody come FIRST, then three that every pair alone can be kept
    apart but together cannot (robot 3 must wait ≥ 2 s for robot 4 and ≤ 0.75 s for robot 5).
    Searching all six at once tried every delay of the first three (81^3 before robot 3); in
    groups the impossible group is refused at its root: one search node."""
    nodes = []
    place = booth_stagger._place
    monkeypatch.setattr(booth_stagger, "_place", lambda *a: (nodes.append(1), place(*a))[1])

    def at(*pts: tuple[float, ...]) -> np.ndarray:
        return np.array(pts, float)[:, None, :]

    far = [at(*[(10.0 * k, 10.0, 0.0)] * 5) for k in range(1, 4)]
    o, b = (0.0, 0.0, 0.0), (5.0, 0.0, 0.0)
    p0, p1 = at(*[o] * 78, b, b), at(*[b] * 86, (0.0, 5.0, 0.0), (0.0, 5.0, 0.0))
    p4 = at((0.0, -5.0, 0.0), o, o, o)
    with pytest.raises(BoothError, match="robot 4's arm comes closer than 0.5 m to robot 3's"):
        stagger_starts([*far, p0, p1, p4], 0.25, 0.5)
    assert len(nodes) == 1
    # the far robots start at once; the feasible pair alone gets its own delays
    nodes.clear()
    assert stagger_starts([*far, p0, p1], 0.25, 0.5) == [0, 0, 0, 8, 0]
    # in every order of the three, the refusal names two robots that do meet at some delay
    # difference (p1 and p4 never come within 5 m of each other)
    for order in itertools.permutations(range(3)):
        paths = [(p0, p1, p4)[k] for k in order]
        with pytest.raises(BoothError, match="arm comes closer") as err:
            stagger_starts(paths, 0.25, 0.5)
        k, i = (int(x) for x in re.findall(r"robot (\d+)'s", str(err.value))[:2])
        offsets = np.arange(-80, 81)
        assert not booth_stagger.pair_offsets_ok(paths[k], paths[i], offsets, 0.5).all()


def _spoke(rng: np.random.Generator, angle_rad: float) -> np.ndarray:
    """(K, 2, 3) a robot's points running in along a spoke at angle_rad to 0.2 m from the
    centre, staying there 1-4 samples, and out again; 0.6 m further out a sample."""
    k, w = int(rng.integers(5, 30)), int(rng.integers(1, 5))
    c = int(rng.integers(1, max(2, k - w - 1)))
    i = np.arange(k)
    r = 0.2 + 0.6 * np.maximum(0, np.maximum(c - i, i - (c + w - 1)))
    p = np.column_stack([r * np.cos(angle_rad), r * np.sin(angle_rad), 0.0 * r])
    return np.stack([p, 1.1 * p], axis=1)


def test_stagger_of_one_crowded_group_is_the_brute_force_optimum(monkeypatch):
    """Four and five robots on spokes that each visit the centre once, for 1-4 samples, at a
    time of their own (so the robots form one group of those that may meet), programs of
    different lengths: the search's delays, with its cuts (the best cycle so far bounds every
    later robot's delay, the later robots' delays are kept arc consistent, a branch that only
    ties the best is left), equal the brute force's over every combination on every random
    case, and the refused cases are refused by both."""
    monkeypatch.setattr(booth_stagger, "STAGGER_MAX_S", 1.5)     # 7 delays of 0.25 s
    dt, d_m, dmax = 0.25, 0.5, 6
    rng = np.random.default_rng(5)
    solved = refused = crowded = 0
    for case in range(40):
        n = 4 + case % 2
        paths = [_spoke(rng, 2 * np.pi * j / n + rng.normal(0, 0.1)) for j in range(n)]
        ok = {(i, j): booth_stagger.pair_offsets_ok(paths[i], paths[j],
                                                    np.arange(-dmax, dmax + 1), d_m)
              for i in range(n) for j in range(i)}
        crowded += booth_stagger._groups(ok, n) == [list(range(n))]
        if _agrees_with_brute_force(paths, dt, d_m, dmax):
            solved += 1
        else:
            refused += 1
    assert solved >= 20 and refused >= 3 and crowded >= 20
