"""The workloads of :mod:`bench_versus`, each run in a child process under one installation.

``bench_versus.py`` starts ``python versus_workloads.py SPEC`` (``SPEC`` a JSON object) with the
installation under test first on the path. The child reads the data the parent simulated
(``.npz``: measurements, modes, times, inputs, the prior and transition matrix, the system's
name), builds one estimator through switchest's public API, calls it once untimed (the
warm-up: numba's compile or cache load in an installation that has numba kernels; the
discretization caches), then times repeated calls by CPU time (``time.process_time``) until
:data:`MIN_SAMPLE_CPU` CPU-s have passed (at least one call), and prints one JSON line: the CPU
and wall seconds per call, the calls, the warm-up's CPU seconds, where switchest was imported
from and whether numba was. With ``"save"`` it also writes the last estimate's ``x`` and ``P``
there, for the parent to compare the installations.

This module imports nothing at its top but the standard library and NumPy, so that it runs
under any installation (the API it calls is the same in all of them).
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np

MIN_SAMPLE_CPU = 0.2  # CPU seconds of repeated calls per timed sample
SEED = 20240607  # the RBPF's random streams


def make_system(name: str):
    """The data set's system, by name: the boost converter or the vehicle."""
    from switchest import models

    if name == "boost":
        return models.boost_converter(process_noise=1.0)  # as bench_switch_time.py
    if name == "vehicle":
        return models.vehicle_2d(measurement_variance=0.05, process_noise=1e-3)  # bench_imm.py
    raise ValueError(f"unknown system {name!r}")


def make_call(spec: dict, system, data: dict):
    """The workload of ``spec`` as a call of no argument returning an ``Estimate``."""
    from switchest import estimators

    y, mode, t, u = data["y"], data["mode"], data["t"], data["u"]
    x0, P0, transition = data["x0"], data["P0"], data["transition"]
    kind = spec["kind"]
    if kind == "kalman":
        f = estimators.ModeKalmanFilter(system, x0, P0)
        return lambda: f.run(y, u, t, modes=mode)
    if kind == "imm":
        f = estimators.IMMFilter(system, transition, x0, P0)
        return lambda: f.run(y, u, t)
    if kind == "imm-smooth":
        f = estimators.IMMFilter(system, transition, x0, P0)
        return lambda: f.smooth(y, u, t)
    if kind == "gpb2":
        f = estimators.GPB2Filter(system, transition, x0, P0)
        return lambda: f.run(y, u, t)
    if kind in ("grid", "refine"):
        f = estimators.SwitchTimeKalmanFilter(system, x0, P0, grid=spec["grid"],
                                              refine=kind == "refine")
        return lambda: f.run(y, u, t, modes=mode)
    if kind == "imm-ev1":
        f = estimators.IMMEV1Filter(system, x0=x0, P0=P0, grid=spec["grid"])
        return lambda: f.run(y, u, t)
    if kind == "rbpf":
        f = estimators.RBPFilter(system, transition, x0, P0, particles=spec["particles"],
                                 rng=SEED)
        return lambda: f.run(y, u, t)
    raise ValueError(f"unknown workload kind {kind!r}")


def run_spec(spec: dict) -> dict:
    """Build, warm up and time the workload of ``spec``; what the child prints."""
    import switchest

    with np.load(spec["data"]) as stored:
        data = {key: stored[key] for key in stored.files}
    for key in ("y", "mode"):  # the first trials (a C-contiguous slice)
        data[key] = np.ascontiguousarray(data[key][:spec["trials"]])
    call = make_call(spec, make_system(str(data["system"])), data)
    start = time.process_time()
    call()
    warmup = time.process_time() - start
    calls = 0
    start_cpu, start_wall = time.process_time(), time.perf_counter()
    while True:
        est = call()
        calls += 1
        if time.process_time() - start_cpu >= MIN_SAMPLE_CPU:
            break
    cpu, wall = time.process_time() - start_cpu, time.perf_counter() - start_wall
    if spec.get("save"):
        arrays = {"x": est.x}
        if est.P is not None:
            arrays["P"] = est.P
        np.savez(spec["save"], **arrays)
    return {"cpu": cpu / calls, "wall": wall / calls, "calls": calls, "warmup_cpu": warmup,
            "switchest": switchest.__file__, "numba_loaded": "numba" in sys.modules}


if __name__ == "__main__":
    print(json.dumps(run_spec(json.loads(sys.argv[1]))))
