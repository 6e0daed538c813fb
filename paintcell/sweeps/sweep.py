"""`paintcell sweep`: many runs of one scenario under sampled tolerances, on Dask.

The client plans the scenario once (surface, plan, 1 kHz program, planned and trajectory films),
sends that payload to every worker once, runs the nominal sample first, then the design's samples
(`paintcell.validation.sweep_spec`). Workers are a `distributed.LocalCluster` of processes by
default, or an existing cluster (`scheduler="tcp://host:8786"`).

Results folder (written as samples finish; every file atomically):

    sweep.json            the spec, the scenario and the sweep's digest (what a resume checks)
    nominal.json          the nominal run's record
    samples/000042.json   one record a sample (factors, seed, metrics, pass/fail, timings)
    summary.json          statistics (`sweeps.sweep_stats`), rewritten as samples arrive
    report.html, *.png    the sweep report (at the end)

A sweep that stops (killed, interrupted, a lost worker) resumes in the same folder: samples
whose file exists are not run again. A sample's result depends on (seed, index) only, so the
same seed gives the same records with any number of workers.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from paintcell.core.atomic_io import atomic_write_text
from paintcell.sweeps.sweep_worker import booth_payload, one_robot_payload, run_sample
from paintcell.validation.sweep_spec import SweepError, SweepSpec

_log = logging.getLogger(__name__)

#: summary.json is rewritten at most this often while samples stream in [s].
SUMMARY_EVERY_S = 2.0


@dataclass
class SweepResult:
    """The records of a finished sweep (sorted by index) and where they were written."""

    out_dir: Path
    spec: SweepSpec
    nominal: dict[str, Any]
    samples: list[dict[str, Any]]
    summary: dict[str, Any]
    ran: int            # samples run by this call (the rest were found from an earlier run)
    wall_s: float
    prepare_s: float


def sample_path(out_dir: Path, index: int) -> Path:
    """Where sample `index`'s record is written."""
    return out_dir / "samples" / f"{index:06d}.json"


def prepare_payload(scn: Any, spec: SweepSpec, fast: bool, mode: str) -> Any:
    """Plan once: surface, plan, program and the two films every sample reuses (a booth: its
    programs and films; `paintcell.sweeps.sweep_worker`)."""
    from paintcell.booth.booth import Booth

    build = booth_payload if isinstance(scn, Booth) else one_robot_payload
    return build(scn, spec.names, spec_digest(scn, spec, fast, mode), fast, mode)


def check_factors_fit(scn: Any, spec: SweepSpec) -> None:
    """One-line SweepError when a factor does not apply to this kind of scenario (a booth
    takes every factor, on every robot; the single-robot cell has no line speed)."""
    from paintcell.booth.booth import Booth
    from paintcell.validation.sweep_names import BOOTH_ONLY_FACTORS

    if isinstance(scn, Booth):
        return
    booth_only = [n for n in spec.names if n in BOOTH_ONLY_FACTORS]
    if booth_only:
        raise SweepError(f"factor(s) {booth_only} need a conveyor: the single-robot cell has no "
                         "conveyor; sweep a booth scenario (e.g. scenarios/booth.toml)")


def sample_function(payload: Any) -> Callable[..., dict[str, Any]]:
    """The function that runs one sample of this payload (any cell: `run_sample`)."""
    return run_sample


def spec_digest(scn: Any, spec: SweepSpec, fast: bool, mode: str) -> str:
    """Digest of (spec, scenario, fast, mode): a results folder resumes only the same sweep."""
    d = scn.to_dict()
    d.pop("source", None)   # where the file is does not change a sample
    d.pop("sweep", None)    # the spec is digested itself; limits do not change a sample
    return spec.digest({"scenario": d, "fast": fast, "mode": mode})


def _claim_folder(out_dir: Path, header: dict[str, Any]) -> None:
    """Create the folder, or check that it holds the same sweep (resume); refuse otherwise."""
    meta = out_dir / "sweep.json"
    if out_dir.exists() and not out_dir.is_dir():
        raise SweepError(f"--out {out_dir} is a file; give a folder for the sweep results")
    if meta.exists():
        try:
            old = json.loads(meta.read_text())
        except (OSError, ValueError) as exc:
            raise SweepError(f"{meta} is unreadable ({exc}); remove the folder or choose "
                             "another --out") from None
        if old.get("digest") != header["digest"]:
            raise SweepError(f"{out_dir} holds a different sweep (other factors, samples, seed "
                             "or scenario); choose another --out or delete it to start over")
        return
    if out_dir.exists() and any(out_dir.iterdir()):
        raise SweepError(f"--out {out_dir} exists and is not a sweep results folder; choose "
                         "another folder or empty it")
    (out_dir / "samples").mkdir(parents=True, exist_ok=True)
    atomic_write_text(meta, json.dumps(header, indent=2, default=str))


def _read_done(out_dir: Path, n: int) -> dict[int, dict[str, Any]]:
    """Sample records already in the folder (a resume); unreadable files are run again."""
    done: dict[int, dict[str, Any]] = {}
    for f in sorted((out_dir / "samples").glob("*.json")):
        try:
            rec = json.loads(f.read_text())
        except (OSError, ValueError):
            continue
        i = rec.get("index")
        if isinstance(i, int) and 0 <= i < n:
            done[i] = rec
    return done


def run_sweep(scn: Any, spec: SweepSpec, out_dir: str | Path, *, fast: bool = False,
              mode: str = "servo", workers: int = 2, scheduler: str | None = None,
              progress: bool = True, report: bool = True,
              on_sample: Callable[[dict[str, Any]], None] | None = None) -> SweepResult:
    """Run (or resume) the sweep; write its results into `out_dir` as they finish.

    One writer at a time: the sweep holds the results-folder lock of `out_dir`
    (`paintcell.core.results_dir.lock_results`), so a second sweep into the same folder is
    refused at once, naming the first.
    workers: processes of the local cluster (0: run in this process, no Dask — for debugging
    and tiny sweeps); ignored when `scheduler` (a Dask scheduler address) is given.
    on_sample: called with each record as it is written (tests use it to interrupt a sweep).
    """
    from paintcell.core.results_dir import lock_results

    with lock_results(Path(out_dir), "sweep"):
        return _run_sweep(scn, spec, out_dir, fast=fast, mode=mode, workers=workers,
                          scheduler=scheduler, progress=progress, report=report,
                          on_sample=on_sample)


def _run_sweep(scn: Any, spec: SweepSpec, out_dir: str | Path, *, fast: bool, mode: str,
               workers: int, scheduler: str | None, progress: bool, report: bool,
               on_sample: Callable[[dict[str, Any]], None] | None) -> SweepResult:
    from tqdm import tqdm

    from paintcell.sweeps.sweep_stats import summarize

    if mode not in ("servo", "kinematic"):
        raise SweepError(f"mode {mode!r} must be 'servo' or 'kinematic'")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 0:
        raise SweepError(f"--workers {workers!r} must be an int >= 0")
    out_dir = Path(out_dir)
    t_start = time.perf_counter()
    check_factors_fit(scn, spec)
    if scheduler is not None:
        _connect(scheduler).close()   # a wrong address fails now, not after planning
    digest = spec_digest(scn, spec, fast, mode)
    header = {"format": "paintcell.Sweep/1", "digest": digest, "spec": spec.to_dict(),
              "scenario": scn.to_dict(), "fast": fast, "mode": mode}
    _claim_folder(out_dir, header)
    done = _read_done(out_dir, spec.samples)
    design, seeds = spec.design(), spec.sample_seeds()
    todo = [i for i in range(spec.samples) if i not in done]
    nominal_file = out_dir / "nominal.json"
    nominal = json.loads(nominal_file.read_text()) if nominal_file.exists() else None

    t0 = time.perf_counter()
    finished = not todo and nominal is not None   # a rerun of a complete sweep: summary only
    payload = None if finished else prepare_payload(scn, spec, fast, mode)
    prepare_s = time.perf_counter() - t0
    records = dict(done)
    bar = tqdm(total=spec.samples, initial=len(done), desc=f"sweep {scn.name}", unit="sample",
               disable=None if progress else True)
    last_summary = [0.0]

    def write_summary(final: bool = False) -> dict[str, Any]:
        summ = summarize(spec, nominal, [records[i] for i in sorted(records)],
                         scn.sweep.get("limits"))
        summ["complete"] = final and len(records) == spec.samples
        atomic_write_text(out_dir / "summary.json", json.dumps(summ, indent=2, allow_nan=False))
        last_summary[0] = time.perf_counter()
        return summ

    def store(rec: dict[str, Any]) -> None:
        atomic_write_text(sample_path(out_dir, rec["index"]), json.dumps(rec, indent=1))
        records[rec["index"]] = rec
        bar.update(1)
        if time.perf_counter() - last_summary[0] > SUMMARY_EVERY_S:
            write_summary()
        if on_sample is not None:
            on_sample(rec)

    try:
        if payload is None:
            pass
        elif workers == 0 and scheduler is None:
            run = sample_function(payload)
            if nominal is None:
                nominal = run(payload, -1, None, 0)
                atomic_write_text(nominal_file, json.dumps(nominal, indent=1))
            for i in todo:
                store(run(payload, i, design[i], int(seeds[i])))
        else:
            nominal = _run_dask(payload, nominal, nominal_file, todo, design, seeds, store,
                                workers, scheduler)
    finally:
        bar.close()
    summary = write_summary(final=True)
    if report:
        from paintcell.sweeps.sweep_report import write_sweep_report

        write_sweep_report(out_dir)
    return SweepResult(out_dir, spec, nominal or {}, [records[i] for i in sorted(records)],
                       summary, len(todo), time.perf_counter() - t_start, prepare_s)


#: samples sent again after the scheduler forgot them (their worker died with their inputs).
MAX_RESUBMITS = 8


def _run_dask(payload: Any, nominal: dict[str, Any] | None, nominal_file: Path,
              todo: list[int], design: np.ndarray, seeds: np.ndarray,
              store: Callable[[dict[str, Any]], None], workers: int,
              scheduler: str | None) -> dict[str, Any]:
    """Nominal first, then every sample in `todo`, streamed to `store` as they complete."""
    from concurrent.futures import CancelledError
    from contextlib import ExitStack

    from distributed import as_completed

    from paintcell.sweeps.dask_cluster import ClusterError, dask_client

    run = sample_function(payload)
    with ExitStack() as stack:
        try:
            client = stack.enter_context(dask_client(workers, scheduler))
        except ClusterError as exc:
            raise SweepError(str(exc)) from None
        [pf] = client.scatter([payload], broadcast=True, hash=False)
        if nominal is None:
            nominal = client.submit(run, pf, -1, None, 0, pure=False,
                                    retries=3).result()
            atomic_write_text(nominal_file, json.dumps(nominal, indent=1))
        def submit(i: int, attempt: int, data: Any) -> Any:
            return client.submit(run, data, i, design[i], int(seeds[i]), pure=False, retries=3,
                                 key=f"paintcell-sample-{payload.digest}-{i}-{attempt}")

        futs = [submit(i, 0, pf) for i in todo]
        index = {f.key: i for f, i in zip(futs, todo, strict=True)}
        resubmitted = 0
        done = as_completed(futs)
        for fut in done:
            try:
                rec = fut.result()
            except CancelledError:
                # The scheduler forgot the task (a worker died holding its inputs while the
                # cluster was busy): send the payload again and run the sample anew.
                if resubmitted >= MAX_RESUBMITS:
                    raise
                resubmitted += 1
                _log.warning("sample %d: the Dask scheduler lost its inputs (a worker died "
                             "holding them); sent again (%d of at most %d)", index[fut.key],
                             resubmitted, MAX_RESUBMITS)
                [pf] = client.scatter([payload], broadcast=True, hash=False)
                new = submit(index[fut.key], resubmitted, pf)
                index[new.key] = index[fut.key]
                done.add(new)
                continue
            store(rec)
            fut.release()
    return nominal


def _connect(scheduler: str) -> Any:
    """A `distributed.Client` of the cluster at `scheduler`, or a one-line SweepError."""
    from paintcell.sweeps.dask_cluster import ClusterError, connect

    try:
        return connect(scheduler)
    except ClusterError as exc:
        raise SweepError(str(exc)) from None
