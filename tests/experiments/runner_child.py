"""A run of an experiment in a child process, for the runner's resilience tests.

``python runner_child.py JSON`` where JSON holds ``name``, ``overrides`` (of the quick
parameters), ``store``, ``workers`` and optionally:

- ``log``: a file that gets the key of every task this process computes, one a line
  (in-process runs only: a pool's workers cannot pickle the counting wrapper);
- ``ready`` and ``go``: touch ``ready`` once imported, then wait for ``go`` to exist,
  so that two children start computing together.

On ``RunInterrupted`` it prints ``{"stored": ..., "total": ..., "caught": TIME}`` (``TIME``
from ``time.time()``, when the runner had stopped) and exits with 130.
"""

import json
import signal
import sys
import time
from pathlib import Path

from switchest.experiments import RunInterrupted, Store, get, run_experiment, runner
from switchest.experiments.store import task_key


def main(spec: dict) -> int:
    # Ctrl-C as in a terminal, whatever this process inherited: a suite started as a background
    # job of a non-interactive shell (nohup ... &) runs with SIGINT ignored, and Python then
    # installs no handler of its own
    signal.signal(signal.SIGINT, signal.default_int_handler)
    experiment = get(spec["name"])
    params = experiment.params(quick=True, **spec["overrides"])
    if spec.get("log"):
        compute = runner.execute_task

        def logged(name, config, seed):
            outcome = compute(name, config, seed)
            with open(spec["log"], "a") as f:
                f.write(task_key(name, config, seed) + "\n")
            return outcome

        runner.execute_task = logged
    if spec.get("go"):
        Path(spec["ready"]).touch()
        while not Path(spec["go"]).exists():
            time.sleep(0.01)
    try:
        run_experiment(experiment, params, store=Store(spec["store"]), workers=spec["workers"])
    except RunInterrupted as exc:
        caught = time.time()
        print(json.dumps({"stored": exc.stored, "total": exc.total, "caught": caught}), flush=True)
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main(json.loads(sys.argv[1])))
