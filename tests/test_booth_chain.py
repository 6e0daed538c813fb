"""A booth robot with more than one job (`paintcell.booth.booth_chain`,
`paintcell.booth.booth.rank_allocations` with max_jobs_per_robot > 1), against independent
truth: a brute-force enumeration of the allocations, the chained program re-measured (its pieces
verbatim, the joining move inside the joint, velocity and acceleration limits by finite
differences, its TCP by forward kinematics), and the film of a two-job robot equal to the sum of
its jobs' films, each at its own flow (superposition)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from paintcell.booth.booth import BoothError, Job, estimate_s, rank_allocations
from paintcell.booth.booth_chain import chain_programs, job_windows
from paintcell.booth.booth_film import gun_in_body, job_paint
from paintcell.booth.booth_hold import delayed
from paintcell.booth.booth_programs import _longest_program_s
from paintcell.motion.joint_trajectory import PAINT, RETRACT, JointTrajectory
from paintcell.motion.moves import plan_move
from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition import thickness
from paintcell.robots import load_robot

DT = 0.004


def test_multi_job_allocation_is_the_brute_force_optimum():
    """rank_allocations(max_jobs_per_robot=2) against an independent enumeration: every part
    whole or cut in two, every job to a robot that reaches it, every robot 1–2 jobs; the best
    by the lexicographic min-max of the robots' summed estimates. No ranked allocation gives
    one robot both pieces of a part."""
    rng = np.random.default_rng(7)
    n_passes = [3, 2, 4]
    durations = [rng.uniform(2, 5, n) for n in n_passes]
    reach = {(r, p): rng.random(n) < 0.8 for r in range(2) for p, n in enumerate(n_passes)}

    def reachable(r: int, job: Job) -> bool:
        return bool(reach[(r, job.part)][job.first:job.end].all())

    ranked, record = rank_allocations(2, n_passes, durations, reachable, max_jobs_per_robot=2)
    best = None
    cuts = [[[(p, 0, n)]] + [[(p, 0, k), (p, k, n)] for k in range(1, n)]
            for p, n in enumerate(n_passes)]
    for cut in itertools.product(*cuts):
        jobs = [j for c in cut for j in c]
        for owners in itertools.product(range(2), repeat=len(jobs)):
            load = [0.0, 0.0]
            count = [0, 0]
            ok = True
            for (p, a, b), r in zip(jobs, owners, strict=True):
                ok &= reachable(r, Job(p, a, b))
                load[r] += estimate_s(durations[p][a:b])
                count[r] += 1
            if ok and all(1 <= c <= 2 for c in count):
                key = tuple(sorted(load, reverse=True))
                best = key if best is None or key < best else best
    assert best is not None
    assert record["estimated_programs_s"] == pytest.approx(list(best), rel=1e-12)
    top = ranked[0]
    covered = sorted((j.part, i) for js in top.values() for j in js for i in range(j.first, j.end))
    assert covered == sorted((p, i) for p, n in enumerate(n_passes) for i in range(n))
    assert all(1 <= len(js) <= 2 for js in top.values())
    # no robot gets both pieces of one part (the whole part is the same passes, estimated
    # APPROACH_RETRACT_S - TURN_S shorter), and the brute force above, which allows it, agrees
    assert ranked and all(len({j.part for j in js}) == len(js) for c in ranked for js in c.values())


def test_patch_part_wings_to_robots_is_the_brute_force_optimum():
    """A part of two patches (5 + 4 passes, as a body and a tongue band painted one after the
    other) where robot 0 reaches only each patch's first passes (one wing) and robot 1 only its
    last ones: no cut in two pieces serves them, one wing of each patch per robot does. Against
    an independent enumeration of every partition of the passes into contiguous pieces with at
    most one cut inside each patch (the seam cut or not), each piece to a robot that reaches it,
    1–3 pieces per robot and no robot two touching pieces (their union is a partition too)."""
    counts = [5, 4]
    n = sum(counts)
    rng = np.random.default_rng(3)
    durations = [rng.uniform(2, 5, n), rng.uniform(2, 5, 3)]
    wing0 = np.array([1, 1, 1, 0, 0, 1, 1, 0, 0], bool)        # robot 0's side of each patch
    reach = {(0, 0): wing0, (1, 0): ~wing0 | np.array([0, 0, 1, 0, 0, 0, 0, 0, 0], bool),
             (0, 1): np.ones(3, bool), (1, 1): np.ones(3, bool)}

    def reachable(r: int, job: Job) -> bool:
        return bool(reach[(r, job.part)][job.first:job.end].all())

    with pytest.raises(BoothError):          # whole or two pieces: nothing works
        rank_allocations(2, [n, 3], durations, reachable, max_jobs_per_robot=3)
    ranked, record = rank_allocations(2, [n, 3], durations, reachable, max_jobs_per_robot=3,
                                      patches=[counts, None])
    best = None
    seam = counts[0]
    for mask in itertools.product((0, 1), repeat=n - 1):       # every cut set of part 0
        cuts = [k + 1 for k, m in enumerate(mask) if m]
        if sum(1 for c in cuts if c < seam) > 1 or sum(1 for c in cuts if c > seam) > 1:
            continue
        edges = [0, *cuts, n]
        pieces0 = list(zip(edges[:-1], edges[1:], strict=True))
        for cut1 in [[(0, 3)]] + [[(0, k), (k, 3)] for k in (1, 2)]:
            jobs = [(0, a, b) for a, b in pieces0] + [(1, a, b) for a, b in cut1]
            if len(jobs) > 6:
                continue
            for owners in itertools.product(range(2), repeat=len(jobs)):
                load, count, ok = [0.0, 0.0], [0, 0], True
                for (p, a, b), r in zip(jobs, owners, strict=True):
                    ok &= reachable(r, Job(p, a, b))
                    load[r] += estimate_s(durations[p][a:b])
                    count[r] += 1
                touching = any(o1 == o2 and p1 == p2 and (b1 == a2 or b2 == a1)
                               for (p1, a1, b1), o1 in zip(jobs, owners, strict=True)
                               for (p2, a2, b2), o2 in zip(jobs, owners, strict=True))
                if ok and not touching and all(1 <= c <= 3 for c in count):
                    key = tuple(sorted(load, reverse=True))
                    best = key if best is None or key < best else best
    assert best is not None
    assert record["estimated_programs_s"] == pytest.approx(list(best), rel=1e-12)
    top = ranked[0]
    covered = sorted((j.part, i) for js in top.values() for j in js for i in range(j.first, j.end))
    assert covered == sorted((p, i) for p, m in enumerate([n, 3]) for i in range(m))
    assert any(len({j.part for j in js}) < len(js) for js in top.values())   # two wings
    assert all(reachable(r, j) for r, js in top.items() for j in js)


def _program(robot, q0: np.ndarray, q1: np.ndarray, paint_frac: tuple[float, float],
             v: np.ndarray, a: np.ndarray, j: np.ndarray) -> JointTrajectory:
    """A rest-to-rest program q0 -> q1 (ruckig) with the brush on over paint_frac of it."""
    z = np.zeros(len(q0))
    mv = plan_move(q0, z, z, q1, z, z, v, a, j)
    t = DT * np.arange(int(np.ceil(mv.duration_s / DT)) + 1)
    q, qd, qdd = mv.sample(np.minimum(t, mv.duration_s))
    T = robot.fk_many(q)
    on = (t >= paint_frac[0] * t[-1]) & (t <= paint_frac[1] * t[-1])
    return JointTrajectory(
        t_s=t, q=q, qd=qd, qdd=qdd, tcp_pos_world=T[:, :3, 3], tcp_rot_world=T[:, :3, :3],
        v_tcp_planned=np.where(on, 0.4, 0.0), paint_on=on, pass_index=np.where(on, 0, -1),
        segment=np.where(on, PAINT, RETRACT), s_pass_m=np.where(on, 0.0, np.nan),
        robot_name=robot.name, joint_names=tuple(f"joint{k + 1}" for k in range(len(q0))),
        meta={"limits": {"v_used_rad_s": v.tolist(), "a_used_rad_s2": a.tolist(),
                         "j_used_rad_s3": j.tolist()}})


def test_two_jobs_chain_and_film_superposition():
    """A robot with two jobs whose homes differ: the chained program holds both verbatim, the
    joining move is at rest at both ends and inside the joint, velocity and acceleration limits
    (re-measured by finite differences), its TCP is the forward kinematics; on the booth clock
    (a start delay) the film credited per job at its own flow is the sum of the two programs'
    films computed alone (superposition, to round-off)."""
    robot = load_robot("irb5500")
    v = 0.5 * np.asarray(robot.v_max, float)
    a = 0.5 * np.asarray(robot.a_max, float)
    j = a / 0.1
    home = np.asarray(robot.q_home, float)
    far = home + np.array([0.4, 0.2, -0.1, 0.3, 0.2, 0.5])
    home_b = home + np.array([0.0, 0.0, 0.0, 0.6, 0.0, -0.6])     # the next job's start
    p1 = _program(robot, home, far, (0.3, 0.7), v, a, j)
    p2 = _program(robot, home_b, far + 0.1, (0.2, 0.9), v, a, j)
    ch = chain_programs([p1, p2], robot)
    K1, K2 = len(p1.t_s), len(p2.t_s)
    np.testing.assert_array_equal(ch.q[:K1], p1.q)
    np.testing.assert_array_equal(ch.q[-K2:], p2.q)
    move = ch.q[K1 - 1:len(ch.t_s) - K2 + 1]          # from p1's end to p2's start
    assert ch.meta["transfer_moves_s"][0] > 0 and len(move) > 2
    qd_fd = np.diff(move, axis=0) / DT
    qdd_fd = np.diff(move, 2, axis=0) / DT**2
    assert np.all(np.abs(qd_fd) <= v * 1.001)
    assert np.all(np.abs(qdd_fd) <= a * 1.05)
    assert np.all(move >= robot.q_lower) and np.all(move <= robot.q_upper)
    mid = K1 + (len(move) - 2) // 2
    np.testing.assert_allclose(ch.tcp_pos_world[mid], robot.fk(ch.q[mid])[:3, 3], atol=1e-12)
    assert not ch.paint_on[K1:len(ch.t_s) - K2].any()
    assert ch.meta["job_starts_s"][1] == pytest.approx((len(ch.t_s) - K2) * DT)
    assert ch.pass_index[-K2:][p2.pass_index >= 0].min() == 1       # run on across the jobs
    # the allocation's skip bound for a robot whose jobs were built together: the chained
    # program, the move between the jobs included (the jobs' programs alone are shorter)
    own = (Job(0, 0, 1), Job(1, 0, 1))
    cache = {(0, own[0]): p1, (0, own[1]): p2}
    alone = _longest_program_s({0: own}, cache, [], DT)
    built = _longest_program_s({0: own}, cache, [], DT, {(0, own): len(ch.t_s)})
    assert alone == pytest.approx((K1 - 1 + K2 - 1) * DT)
    assert built == pytest.approx(ch.t_s[-1] - ch.t_s[0]) and built > alone

    n_delay = 37
    booth_clock = delayed(ch, n_delay)
    w = job_windows(booth_clock, 2)
    assert not (w[0] & w[1]).any() and (w[0] | w[1]).all()
    app = Applicator.default()
    apps = [app, app.scaled(1.7)]
    pts = np.array([[x, y, 0.0] for x in np.linspace(0.3, 1.6, 14)
                    for y in np.linspace(-0.8, 0.8, 14)])
    nrm = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    plans = [type("P", (), {"applicator": ap})() for ap in apps]
    jobs = (Job(0, 0, 1), Job(1, 0, 1))
    t = booth_clock.t_s
    zero = np.zeros(len(t))
    chained = np.zeros(len(pts))
    for ap, on in job_paint(plans, jobs, booth_clock):
        g = gun_in_body(t, booth_clock.tcp_pos_world, booth_clock.tcp_rot_world, on, np.eye(4),
                        zero, np.array([1.0, 0, 0]), brush=booth_clock.flow)
        chained += thickness(ap, g, pts, nrm)
    alone = np.zeros(len(pts))
    for ap, p in zip(apps, (p1, p2), strict=True):
        alone += thickness(ap, gun_in_body(p.t_s, p.tcp_pos_world, p.tcp_rot_world, p.paint_on,
                                           np.eye(4), np.zeros(len(p.t_s)),
                                           np.array([1.0, 0, 0]), brush=p.flow), pts, nrm)
    assert alone.max() > 0
    np.testing.assert_allclose(chained, alone, rtol=1e-9, atol=1e-12 * alone.max())


def test_jobs_per_robot_and_part_robots_keys(tmp_path):
    """TOML `max_jobs_per_robot`, `[[parts]] robots` and a two-job `[allocation]` are read;
    bad values are refused with one line."""
    from paintcell.app.scenario_files import load_scenario
    from paintcell.booth.booth_data import BoothDataError

    f = tmp_path / "b.toml"
    head = 'name = "b"\nmax_jobs_per_robot = {m}\n[[parts]]\npart = "door"\nrobots = {r}\n'
    tail = '[[robots]]\nname = "a"\n[[robots]]\nname = "c"\n'
    f.write_text(head.format(m=2, r='["a"]') + tail
                 + '[allocation]\na = [[0, 0, 2], [0, 2, 4]]\nc = [0, 4, 5]\n')
    b = load_scenario(f)
    assert b.max_jobs_per_robot == 2 and b.parts[0].robots == ("a",)
    assert b.allocation == {"a": ((0, 0, 2), (0, 2, 4)), "c": (0, 4, 5)}
    f.write_text(head.format(m=0, r='["a"]') + tail)
    with pytest.raises(BoothDataError, match="max_jobs_per_robot = 0 must be 1, 2 or 3"):
        load_scenario(f)
    f.write_text(head.format(m=1, r='["x"]') + tail)
    with pytest.raises(BoothDataError, match=r"part 'door' names robot\(s\) \['x'\]"):
        load_scenario(f)
    f.write_text(head.format(m=1, r='"a"') + tail)
    with pytest.raises(BoothDataError, match="must be a list of robot names"):
        load_scenario(f)
