#!/usr/bin/env python3
"""Reproducibility of ehlsim runs (docs/usage.md, "Reproducibility"):

  reproducibility.py BINARY new-process   the same input in a new process gives
                                          the same bits, on 1 and on 2 threads
                                          (an impact and a rolling contact)
  reproducibility.py BINARY threads       1 and 2 threads give the same bits
                                          (impacts and rolling contacts)
  reproducibility.py BINARY kill-restart [SEED]
                                          runs killed with kill -9 at random
                                          steps and continued with --restart
                                          give the uninterrupted run's bits

Exit code 0 when the property holds, 1 with the differences otherwise.
"""
import os
import random
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import outputs

# 33^2, the paper's M = 100, L = 10 case to lift-off (46 steps, about a second):
# fields every 5 steps and at given times, the spike analysis unfiltered so
# that a spike (and V_s) is found on this coarse grid, a checkpoint every step.
SMALL_CASE = ["--set", "grid.points=33", "--set", "output.snapshot_every=5",
              "--set", "output.snapshot_times=[0.5,2.05,3.3]", "--set", "spike.filter=none",
              "--set", "output.checkpoint_every=1"]
# 65^2 in contact (T = 2.5, 53 steps) and 129^2, whose deformation transforms
# are cut into batches shared by the threads, for a few steps.
THREAD_CASES = [SMALL_CASE,
                ["--set", "grid.points=65", "--set", "time.T_end=2.5",
                 "--set", "output.snapshot_every=10"],
                ["--set", "grid.points=129", "--set", "time.T_end=0.1"]]
# Rolling contacts on 129^2 (the threads share the transforms' batches there):
# the default case, and M = 20, L = 20 with a Roelands, Dowson-Higginson
# lubricant (more cycles, the local Newton step).
ROLLING_CASES = [["--set", "grid.points=129"],
                 ["--set", "grid.points=129", "--set", "case.M=20",
                  "--set", "lubricant.viscosity=roelands", "--set", "lubricant.eta0=0.04",
                  "--set", "lubricant.ph_star=1e9", "--set", "lubricant.z=1",
                  "--set", "lubricant.density=dowson-higginson"]]
KILLS = 10
DEFAULT_SEED = 20240909
# Seconds between looks at the checkpoint of a run that is to be killed.
POLL_SECONDS = 0.002
# The last steps are not targets: the run must not end before the kill lands.
SPARE_STEPS = 4
# Runs started per kill before giving up, should they end before the kill.
KILL_ATTEMPTS = 3


def run(binary, directory, case, threads, extra=(), mode="impact"):
    """`ehlsim MODE` in `directory` with --out run; returns the run directory."""
    directory.mkdir(parents=True)
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), OMP_WAIT_POLICY="passive")
    command = [binary, mode, "--quiet", *case, *extra, "--out", "run"]
    result = subprocess.run(command, cwd=directory, env=env, capture_output=True, text=True)
    if result.returncode != 0:
        sys.exit(f"{' '.join(command)}: exit {result.returncode}\n{result.stderr}")
    return directory / "run"


def report(what, differences):
    """Prints the outcome of one comparison; True when there is no difference."""
    print(f"{what}: {'bit-identical' if not differences else 'DIFFERENT'}")
    for line in differences:
        print("   ", line)
    return not differences


def rows(run_dir):
    return len(outputs.read_rows(run_dir / "timeseries.csv")[1])


def new_process(binary, work):
    ok = True
    for threads in (1, 2):
        a = run(binary, work / f"a{threads}", SMALL_CASE, threads)
        b = run(binary, work / f"b{threads}", SMALL_CASE, threads)
        ok &= report(f"33^2, {rows(a)} steps, {threads} thread(s), two processes",
                     outputs.compare_runs(a, b))
        case = ROLLING_CASES[0]
        a = run(binary, work / f"rolling_a{threads}", case, threads, mode="rolling")
        b = run(binary, work / f"rolling_b{threads}", case, threads, mode="rolling")
        ok &= report(f"rolling {' '.join(case[1::2])}, {threads} thread(s), two processes",
                     outputs.compare_runs(a, b))
    return ok


def threads(binary, work):
    ok = True
    for k, case in enumerate(THREAD_CASES):
        one = run(binary, work / f"one{k}", case, 1)
        two = run(binary, work / f"two{k}", case, 2)
        ok &= report(f"{' '.join(case[1::2])} ({rows(one)} steps): 1 against 2 threads",
                     outputs.compare_runs(one, two))
    for k, case in enumerate(ROLLING_CASES):
        one = run(binary, work / f"rolling_one{k}", case, 1, mode="rolling")
        two = run(binary, work / f"rolling_two{k}", case, 2, mode="rolling")
        ok &= report(f"rolling {' '.join(case[1::2])}: 1 against 2 threads",
                     outputs.compare_runs(one, two))
    return ok


def checkpoint_step(path):
    """The step a checkpoint holds (None while there is none)."""
    result = subprocess.run(["ncdump", "-h", str(path)], capture_output=True, text=True)
    match = re.search(r":step = (\d+) ;", result.stdout)
    return int(match.group(1)) if result.returncode == 0 and match else None


def run_and_kill(binary, directory, target):
    """Starts the small case and kills it (SIGKILL) once its checkpoint holds
    step `target` or later; returns the step of the checkpoint it leaves.
    The run is stopped (SIGSTOP) while a new checkpoint is read, so that it
    does not run ahead of the reading: it is killed wherever it was then,
    typically inside the next step."""
    directory.mkdir(parents=True)
    checkpoint = directory / "run.checkpoint.nc"  # the checkpoint of the run in progress
    process = subprocess.Popen([binary, "impact", "--quiet", *SMALL_CASE, "--out", "run"],
                               cwd=directory, env=dict(os.environ, OMP_NUM_THREADS="1"))
    seen = None
    while process.poll() is None:
        try:
            status = checkpoint.stat()
            stamp = (status.st_ino, status.st_mtime_ns)
        except FileNotFoundError:
            stamp = None
        if stamp != seen:
            seen = stamp
            process.send_signal(signal.SIGSTOP)
            step = checkpoint_step(checkpoint)
            if step is not None and step >= target:
                process.send_signal(signal.SIGKILL)
                break
            process.send_signal(signal.SIGCONT)
        time.sleep(POLL_SECONDS)
    process.wait()
    if process.returncode == 0:
        return None  # it finished between two looks (a very busy machine)
    if process.returncode != -signal.SIGKILL or (directory / "run" / "run.json").exists():
        sys.exit(f"the run aimed at step {target} failed (exit {process.returncode})")
    return checkpoint_step(checkpoint)


def killed_run(binary, directory, target):
    """run_and_kill, tried again when the run ended before the kill; returns
    (run directory, checkpoint step)."""
    for attempt in range(KILL_ATTEMPTS):
        killed = directory / f"attempt{attempt}"
        step = run_and_kill(binary, killed, target)
        if step is not None:
            return killed, step
        print(f"the run aimed at step {target} finished before the kill: again")
    sys.exit(f"the run aimed at step {target} finished before the kill {KILL_ATTEMPTS} times")


def kill_restart(binary, work, seed):
    full = run(binary, work / "full", SMALL_CASE, 1)
    steps = rows(full)
    rng = random.Random(seed)
    targets = rng.sample(range(1, steps - SPARE_STEPS + 1), KILLS)  # distinct steps
    print(f"seed {seed}: kill targets (steps) {targets} of {steps}")
    ok = True
    for k, target in enumerate(targets):
        killed, step = killed_run(binary, work / f"killed{k}", target)
        restarted = run(binary, work / f"restarted{k}", SMALL_CASE, 1,
                        ["--restart", str(killed / "run.checkpoint.nc")])
        ok &= report(f"kill {k + 1}: aimed at step {target}, checkpoint of step {step}, "
                     f"restarted for {rows(restarted)} steps",
                     outputs.compare_restart(full, restarted, step))
    return ok


def main():
    binary, test = str(Path(sys.argv[1]).resolve()), sys.argv[2]
    with tempfile.TemporaryDirectory(prefix="ehlsim-repro-") as temp:
        work = Path(temp)
        if test == "new-process":
            ok = new_process(binary, work)
        elif test == "threads":
            ok = threads(binary, work)
        elif test == "kill-restart":
            ok = kill_restart(binary, work, int(sys.argv[3]) if len(sys.argv) > 3 else DEFAULT_SEED)
        else:
            sys.exit(f"unknown test '{test}'")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
