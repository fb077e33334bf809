"""Fits side by side: independent candidate fits handed to workers (forked processes or Ray).

Every stage that fits several candidates (single fits, partners, pairs, the form
re-judgement) goes through :func:`map_parallel`; the fits are deterministic, so where they
run does not change the result, and each worker's replays come back into the parent's cache.
"""

from __future__ import annotations

import json
import multiprocessing as mp
from typing import Any

from rover_env.calibration.candidates import Candidate
from rover_env.calibration.diagnosis.state import Options, Scored
from rover_env.calibration.fit import Evaluator
from rover_env.calibration.replay import WindowResult, serial_replays
from rover_env.executor import make_executor


def _pool_task(
    shared: dict[str, Any], i: int
) -> tuple[Scored, int, float, dict[tuple[str, str], list[WindowResult]]]:
    serial_replays()  # a forked fit worker: its replays stay in it
    ev: Evaluator = shared["ev"]
    n0, s0, keys0 = ev.replays, ev.seconds, set(ev.cache)
    s = shared["task"](i)
    new = {k: v for k, v in ev.cache.items() if k not in keys0}
    keep = {k: v for k, v in new.items() if k[0] == json.dumps(s.fit.ext, sort_keys=True)}
    s.fit.candidates = []  # Candidate.to_ext is a closure; the parent puts them back
    return s, ev.replays - n0, ev.seconds - s0, keep


def map_candidates(
    fit_one: Any, report: Any, cands: list[Candidate], ev: Evaluator, opts: Options
) -> list[Scored]:
    """``fit_one`` on every candidate, in ``opts.workers`` workers; catalogue order.

    Candidates with several model forms are handed out first: they cost several fits each,
    and the catalogue puts the soil, which has four, last, where the other worker idled
    while it ran (own clean case 10070, 2 workers: 105 s)."""
    order = sorted(range(len(cands)), key=lambda i: -max(1, len(cands[i].forms)))
    return map_parallel(
        lambda i: fit_one(cands[i]), report, len(cands), lambda i: [cands[i]], ev, opts, order
    )


def map_parallel(
    task: Any,
    report: Any,
    n_tasks: int,
    candidates_of: Any,
    ev: Evaluator,
    opts: Options,
    order: list[int] | None = None,
) -> list[Scored]:
    """``task(i)`` for i < n_tasks through ``opts.executor``; results in order (``order``:
    the order the tasks are handed to the workers, longest first).

    The fits are independent and deterministic, so the result does not depend on where they
    run; the workers' replays of each fitted model come back into ``ev.cache``. Local workers
    are forked (they inherit ``task``, a closure); Ray's are sent it once (cloudpickle).
    ``candidates_of(i)`` gives back the candidates of task i's fit (they do not pickle).
    """
    n = min(max(1, int(opts.workers)), n_tasks)
    if opts.executor == "local" and (n <= 1 or "fork" not in mp.get_all_start_methods()):
        out = []
        for i in range(n_tasks):
            out.append(task(i))
            report(out[-1])
        return out
    results: dict[int, Scored] = {}
    with make_executor(opts.executor, n, opts.ray_address, start_method="fork") as ex:
        handed = list(range(n_tasks)) if order is None else list(order)
        for j, (s, replays, seconds, cache) in ex.imap(
            _pool_task, handed, shared={"ev": ev, "task": task}
        ):
            i = handed[j]
            s.fit.candidates = [c.adopt_form(s.fit.ext) for c in candidates_of(i)]
            ev.replays += replays
            ev.seconds += seconds
            ev.cache.update(cache)
            results[i] = s
            report(s)
    return [results[i] for i in range(n_tasks)]
