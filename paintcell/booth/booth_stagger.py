"""Staggered starts of a booth's robots: the start delays that keep every two arms apart and end
the booth soonest (`stagger_starts`), from each pair's clearance per delay difference
(`pair_offsets_ok`).

The search is depth-first over the robots' delays, in lexicographic order of the delays, with
cuts that only drop subtrees holding no complete solution better than the best found, so it
returns the same delays as the plain search. A pair of robots that can be kept apart at no delay
difference is refused before the search. After a robot's delay is fixed, the free delays of
every later robot are narrowed at once (forward checking) to those that keep it apart from the
fixed ones and, once a solution is known, end no later than its cycle; then to arc consistency
among themselves (every delay left of a robot keeps it apart from some delay left of every other
later robot); the branch is left as soon as one has none. A branch is also left when every later
robot at its least delay left gives a longer cycle than the best so far, or the same cycle and
no smaller sum of delays (a tie comes later in lexicographic order, so it loses). Forward
checking keeps a robot that cannot be placed from making the search try every combination of
the earlier robots' delays (81^3 for the fourth robot); the bounds and the arc consistency keep
a cycle set by one robot's long program from making it try every way of delaying the others.

Robots that can never meet (every delay difference keeps them apart) constrain nothing, so the
robots are split into independent groups (the connected components of "may meet") and each
group is searched alone: otherwise a robot that meets nobody, ahead of a group that cannot be
placed, multiplied that group's search by its 81 delays. The groups' best delays make the whole
booth's: the cycle is the longest group's, and a group that ends sooner takes its least delays
that end by then (its own search again with that cycle as a floor; sums and the earliest
robots' delays are separable over groups, so the combination is the plain search's answer).
"""

from __future__ import annotations

import numpy as np

from paintcell.booth.booth import BoothError

#: start-delay step and largest delay of `stagger_starts` [s].
STAGGER_STEP_S, STAGGER_MAX_S = 0.25, 20.0


def pair_offsets_ok(p: np.ndarray, q: np.ndarray, offsets: np.ndarray,
                    min_distance_m: float) -> np.ndarray:
    """(O,) whether two robots' arms stay `min_distance_m` [m] apart when p starts `offsets`
    (O,) samples after q (negative: before). p, q: (K, P, 3) arm points on one clock; each holds
    its first pose before its start and its last after its end, so only the offset matters.

    The close pairs of samples (a of p, b of q) are found with k-d trees; a pair meets on the
    common clock at offset o when p's sample a and q's sample b are shown at one instant: o =
    b − a, or any o ≤ / ≥ that when a or b is a held first / last sample. The offsets are
    multiples of their greatest common divisor m (a stagger's step), so two samples that are
    neither held meet at an offset only when b − a is one too: those pairs are searched among
    the samples of one residue modulo m alone (one tree, the residue a fourth coordinate far
    apart), the held samples against every sample of the other arm."""
    from scipy.spatial import cKDTree

    offsets = np.asarray(offsets)
    Kp, Kq, P = len(p), len(q), p.shape[1]
    m = int(np.gcd.reduce(np.abs(offsets.astype(np.int64)))) if len(offsets) else 1
    m = m if m > 0 else Kp + Kq                      # offset 0 alone: a = b only
    far = 10.0 * (min_distance_m + float(np.ptp(np.concatenate([p, q]).reshape(-1, 3), 0).max())
                  + 1.0)

    def tree(x: np.ndarray, ks: np.ndarray, by_residue: bool) -> cKDTree:
        r = np.repeat((ks % m).astype(float) * far if by_residue else np.zeros(len(ks)), P)
        return cKDTree(np.column_stack([x[ks].reshape(-1, 3), r]))

    def close(kp: np.ndarray, kq: np.ndarray, by_residue: bool) -> np.ndarray:
        """The close sample pairs (a, b) of p's samples kp and q's kq, as a·Kq + b."""
        c = tree(p, kp, by_residue).sparse_distance_matrix(
            tree(q, kq, by_residue), min_distance_m, output_type="ndarray")
        c = c[c["v"] < min_distance_m]
        return kp[c["i"] // P].astype(np.int64) * Kq + kq[c["j"] // P]

    all_p, all_q = np.arange(Kp), np.arange(Kq)
    ends_p, ends_q = np.unique([0, Kp - 1]), np.unique([0, Kq - 1])
    # the distinct sample pairs, one integer each (np.unique over rows is ~10× slower)
    ab = np.unique(np.concatenate([close(all_p, all_q, True), close(ends_p, all_q, False),
                                   close(all_p, ends_q, False)]))
    a, b = ab // Kq, ab % Kq
    lo = np.where((a < Kp - 1) & (b > 0), b - a, np.iinfo(np.int64).min // 2)
    hi = np.where((a > 0) & (b < Kq - 1), b - a, np.iinfo(np.int64).max // 2)
    o = offsets[:, None]
    return ~np.any((lo[None] <= o) & (o <= hi[None]), axis=1)


def stagger_starts(paths: list[np.ndarray], dt_s: float, min_distance_m: float) -> list[int]:
    """Start delays [samples] that keep every two robots' arms `min_distance_m` [m] apart and
    end the booth soonest.

    paths: per robot, positions (K_i, P, 3) [m] of P points along its arm (the bell, the wrist
    centre, the elbow, ...) every dt_s [s]; a delayed robot holds its first pose, a finished one
    its last. Delays are multiples of STAGGER_STEP_S up to STAGGER_MAX_S. Whether two robots
    keep apart depends only on the difference of their delays, so it is measured once per pair
    and difference (`pair_offsets_ok`); a depth-first search over the delays (module doc) then
    takes those with the shortest cycle (max over the robots of delay + program), ties to the
    smallest sum of delays, then to the earliest robots' smallest. Raises BoothError when no
    delays work, naming the robots ("robot 3's ... robot 0's": indices into paths).
    """
    step = max(1, int(round(STAGGER_STEP_S / dt_s)))
    dmax = int(round(STAGGER_MAX_S / dt_s)) // step         # in steps
    rel = np.arange(-dmax, dmax + 1)
    n = len(paths)
    ok = {(i, j): pair_offsets_ok(paths[i], paths[j], rel * step, min_distance_m)
          for i in range(n) for j in range(i)}
    for (i, j), row in ok.items():
        if not row.any():
            raise BoothError(f"robot {i}'s arm comes closer than {min_distance_m} m to robot "
                             f"{j}'s at every start delay up to {STAGGER_MAX_S} s of either; "
                             "change the allocation or the robots' places")
    lens = [len(p) for p in paths]
    groups = _groups(ok, n)
    best = [_search_group(g, ok, lens, step, dmax, 0, min_distance_m) for g in groups]
    cycle = max([lens[k] for k in range(n)] + [b[0][0] for b in best])
    delays = [0] * n                      # a robot that meets nobody starts at once
    for g, b in zip(groups, best, strict=True):
        if b[0][0] < cycle:               # this group may end later: its least delays by then
            b = _search_group(g, ok, lens, step, dmax, cycle, min_distance_m)
        for k, d in zip(g, b[1], strict=True):
            delays[k] = d * step
    return delays


def _groups(ok: dict[tuple[int, int], np.ndarray], n: int) -> list[list[int]]:
    """The robots (indices, ascending) of each group of two or more that may meet: connected
    components of the pairs whose `ok` row is not all True, ordered by their first robot."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    edges = np.array([ij for ij, row in ok.items() if not row.all()], int).reshape(-1, 2)
    _, label = connected_components(
        coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), (n, n)), directed=False)
    out = [[int(k) for k in np.flatnonzero(label == c)] for c in np.unique(label)]
    return sorted((g for g in out if len(g) > 1), key=lambda g: g[0])


def _search_group(g: list[int], ok: dict[tuple[int, int], np.ndarray], lens: list[int],
                  step: int, dmax: int, floor: int, min_distance_m: float
                  ) -> tuple[tuple[int, int, tuple[int, ...]], list[int]]:
    """The best (key, delays [steps]) of group g's robots alone, their cycle counted as at least
    floor [samples]; raises BoothError (robot indices of the whole booth) when none."""
    search = _Search({(a, b): ok[(g[a], g[b])] for a in range(len(g)) for b in range(a)},
                     [lens[k] for k in g], step, dmax, floor)
    _place(search, [], [np.ones(dmax + 1, bool) for _ in g])
    if search.best is None:
        i, k = (g[x] for x in search.dead)
        raise BoothError(f"robot {k}'s arm comes closer than {min_distance_m} m to robot {i}'s "
                         f"or another's for every start delay up to {STAGGER_MAX_S} s that "
                         "keeps those apart; change the allocation or the robots' places")
    return search.best


class _Search:
    """State of `stagger_starts`'s depth-first search: ok[(i, j)] (2 dmax + 1,) whether robot i
    may start (offset − dmax) steps after robot j; lens: program lengths [samples]; floor: the
    cycle [samples] a shorter one counts as (0: none); best: (key, delays [steps]) of the best
    complete solution; dead: (robot, later robot) of the deepest dead end, two that meet at
    some delay difference (the error message). apart[(k, l)] (dmax + 1, dmax + 1): whether
    robot k at delay v and robot l at delay w [steps] keep apart (ok as a table of both delays,
    for the arc consistency)."""

    def __init__(self, ok: dict[tuple[int, int], np.ndarray], lens: list[int], step: int,
                 dmax: int, floor: int = 0) -> None:
        self.ok, self.lens, self.step, self.dmax, self.floor = ok, lens, step, dmax, floor
        self.grid = np.arange(dmax + 1)
        self.best: tuple[tuple[int, int, tuple[int, ...]], list[int]] | None = None
        self.dead = (0, 1)
        self.dead_depth = -1
        diff = self.grid[:, None] - self.grid[None, :] + dmax
        self.apart: dict[tuple[int, int], np.ndarray] = {}
        for (k, j), row in ok.items():
            self.apart[(k, j)] = row[diff]
            self.apart[(j, k)] = self.apart[(k, j)].T


def _consistent(s: _Search, first: int, free: list[np.ndarray]) -> tuple[int, int] | None:
    """Narrows free (the delays of robots first, first + 1, ...) in place to arc consistency:
    every delay left of a robot keeps it apart from some delay left of every other. Returns
    (l, k) when robot k is left with none, robot l the one its last delays met (None: every one
    has some)."""
    changed = True
    while changed:
        changed = False
        for a, fa in enumerate(free):
            for b, fb in enumerate(free):
                if a == b:
                    continue
                kept = fa & (s.apart[(first + a, first + b)] & fb).any(axis=1)
                if kept.sum() < fa.sum():
                    if not kept.any():
                        return first + b, first + a
                    free[a] = fa = kept
                    changed = True
    return None


def _place(s: _Search, d: list[int], free: list[np.ndarray]) -> None:
    """Places robot len(d) given the earlier robots' delays d [steps]; free[k]: the delays of
    every robot k ≥ len(d) that keep it apart from all of d (forward-checked) and leave every
    other later robot some delay (arc consistent)."""
    i, n = len(d), len(s.lens)
    if i == n:
        key = (max([s.floor] + [s.lens[k] + d[k] * s.step for k in range(n)]), sum(d), tuple(d))
        if s.best is None or key < s.best[0]:
            s.best = (key, list(d))
        return
    done = max([s.floor] + [s.lens[k] + d[k] * s.step for k in range(i)])
    summed = sum(d)
    for di in np.flatnonzero(free[i]):
        if s.best is not None and \
                (max(done, s.lens[i] + di * s.step), summed + di) > s.best[0][:2]:
            break                         # larger delays only lengthen it
        later = []
        for k in range(i + 1, n):
            fk = free[k] & s.ok[(k, i)][s.grid - di + s.dmax]
            if s.best is not None:        # a longer cycle than the best's cannot beat it
                fk &= s.lens[k] + s.grid * s.step <= s.best[0][0]
            if not fk.any():              # robot k has no delay left: a dead branch
                if i > s.dead_depth and s.best is None:
                    s.dead, s.dead_depth = (i, k), i
                break
            later.append(fk)
        else:
            met = _consistent(s, i + 1, later)
            if met is not None:           # the later robots cannot all be placed
                if i > s.dead_depth and s.best is None:
                    s.dead, s.dead_depth = met, i
                continue
            # every completion's (cycle, sum) is at least the one with each later robot at its
            # least delay left; the search meets the delays in lexicographic order, so one that
            # only ties the best so far comes later in that order and loses the tie
            least = [int(f.argmax()) for f in later]
            ends = [done, s.lens[i] + int(di) * s.step] + \
                [s.lens[k] + m * s.step for k, m in enumerate(least, i + 1)]
            if s.best is not None and (max(ends), summed + int(di) + sum(least)) >= s.best[0][:2]:
                continue
            _place(s, d + [int(di)], free[:i + 1] + later)
