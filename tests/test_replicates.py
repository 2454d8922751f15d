"""coevo.replicates: the one job loop, here and on Dask; a tiny comparison on a local Dask cluster; faults; Slurm/PBS.

Functions used as replicates are module-level so they can travel to Dask workers (by reference: a local
cluster's workers inherit this process's path; separate processes are given tests/ on PYTHONPATH).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from functools import partial
from pathlib import Path

import pytest
from procs import FINISHED_COMPARISON, coevo_main

from coevo.errors import ConfigError
from coevo.replicates.backends import ClusterLost, LocalBackend, parse_cluster
from coevo.replicates.replicate import Replicate
from coevo.replicates.runner import run_replicates
from coevo.runs.local import wait_until as poll

ROOT = Path(__file__).resolve().parents[1]


# ---------------------------------------------------------------- replicates as functions
def _write(root: Path, name: str, *, fail: bool = False, die_once: bool = False, sleep: float = 0.0) -> None:
    """A replicate: counts its attempts in root/attempts/NAME, then fails, kills its process once, or writes out/NAME."""
    tries = Path(root) / "attempts" / name
    tries.parent.mkdir(parents=True, exist_ok=True)
    with open(tries, "a") as f:
        f.write("x")
    n = len(tries.read_text())
    if die_once and n == 1:
        os._exit(1)  # as if the host (the Dask worker) died under it
    time.sleep(sleep)
    if fail:
        raise RuntimeError(f"{name} breaks for its own reasons")
    (Path(root) / "out").mkdir(exist_ok=True)
    (Path(root) / "out" / name).write_text(name)


def _finished(name: str, root: Path) -> bool:
    return (Path(root) / "out" / name).exists()


def job(name: str, *, after: tuple[str, ...] = (), **kw: object) -> Replicate:
    return Replicate(name=name, output=f"out/{name}", finished=partial(_finished, name), function=_write,
                     kwargs={"name": name, **kw}, after=after)


def attempts(root: Path, name: str) -> int:
    f = root / "attempts" / name
    return len(f.read_text()) if f.exists() else 0


def test_the_runner_runs_reports_failures_with_reasons_and_resumes(tmp_path: Path) -> None:
    reps = [job("a"), job("b", fail=True), job("c", after=("b",)), job("d", after=("a",))]
    prog = run_replicates(reps, tmp_path, LocalBackend(1), poll=0.01)
    assert prog.runs_done == 2 and prog.runs_total == 4
    assert prog.failed == {"b": "RuntimeError: b breaks for its own reasons", "c": "skipped: b, which it needs, failed"}
    assert (tmp_path / "logs" / "b.log").read_text().startswith("RuntimeError")
    assert attempts(tmp_path, "b") == 1 and attempts(tmp_path, "c") == 0  # not retried, not started

    again = run_replicates(reps, tmp_path, LocalBackend(2), poll=0.01)  # --resume: only the unfinished run
    assert attempts(tmp_path, "a") == 1 and attempts(tmp_path, "b") == 2
    assert again.runs_done == 2 and set(again.failed) == {"b", "c"}


def test_coevo_seeds_jobs_counts_learners_and_a_study_counts_live_runs() -> None:
    # coevo seeds --jobs N runs N learners at once (its timing target is per core); a study's --jobs counts live
    # runs, of which an offline learner is half.
    from coevo.experiments.seeds.door import replicates as door_replicates
    from coevo.experiments.seeds.experiment import replicates as learn_replicates

    one = LocalBackend(1)
    try:
        for rep in (learn_replicates(["docking"], [0], [], weight=2)[0],
                    door_replicates([0], generations=2, world={}, failed=[], ga={})[0]):
            assert one.room(0, rep) and not one.room(rep.weight, rep), rep.name
        half = learn_replicates(["docking"], [0], [])[0]
        assert one.room(half.weight, half) and not one.room(2 * half.weight, half)
    finally:
        one.close()


def test_replicates_must_name_what_they_wait_for() -> None:
    with pytest.raises(ValueError, match="not in the list"):
        run_replicates([job("a", after=("zz",))], Path("/nonexistent"), LocalBackend(1))
    with pytest.raises(ValueError, match="command or a function"):
        Replicate(name="x", output="x", finished=bool)


@pytest.mark.parametrize(("text", "parsed"), [("local", ("local", None)), ("local:3", ("local", 3)),
                                              ("slurm:10", ("slurm", 10)), ("pbs", ("pbs", None)),
                                              ("tcp://10.0.0.1:8786", ("address", None))])
def test_cluster_flag(text: str, parsed: tuple[str, int | None]) -> None:
    assert parse_cluster(text) == parsed


@pytest.mark.parametrize("text", ["local:0", "local:x", "slurm:-1", "", "nan", "/tmp/a-file", "tcp://host"])
def test_bad_cluster_flag(text: str) -> None:
    with pytest.raises(ConfigError):
        parse_cluster(text)


# ---------------------------------------------------------------- HPC: the job scripts dask-jobqueue writes
@pytest.mark.parametrize("kind", ["slurm", "pbs"])
def test_the_batch_job_script_from_the_shipped_config(kind: str) -> None:
    from coevo.replicates.backends import _jobqueue

    cluster = _jobqueue(kind, ROOT / "deploy" / "slurm" / "jobqueue.yaml")  # not scaled: nothing is submitted
    try:
        script = cluster.job_script()
    finally:
        cluster.close()
    lines = script.splitlines()
    assert lines[0] == "#!/usr/bin/env bash"
    if kind == "slurm":
        for d in ("#SBATCH -J coevo-dask", "#SBATCH --cpus-per-task=8", "#SBATCH -t 04:00:00", "#SBATCH -n 1"):
            assert d in lines, d
    else:
        for d in ("#PBS -N coevo-dask", "#PBS -l select=1:ncpus=8:mem=16GB", "#PBS -l walltime=04:00:00"):
            assert d in lines, d
    assert 'source "$HOME/coevo/.venv/bin/activate"' in lines
    worker = next(ln for ln in lines if "distributed.cli.dask_worker" in ln).split()
    assert worker[worker.index("--nthreads") + 1] == "1"  # one replicate per Dask worker ...
    assert worker[worker.index("--nworkers") + 1] == "4"  # ... four per job, two cores each (cpus 8)
    assert "--nanny" in worker and worker[worker.index("--death-timeout") + 1] == "120"
    assert worker[3].startswith("tcp://")  # the scheduler this process started, which the jobs call back


# ---------------------------------------------------------------- on Dask
@pytest.mark.service
def test_on_a_local_dask_cluster_a_dead_worker_reruns_its_replicate_and_own_failures_are_not_retried(tmp_path: Path) -> None:
    from coevo.replicates.backends import open_backend

    reps = [job("dies", die_once=True), job("fails", fail=True), job("fine")]
    counted = tmp_path / "shared"  # a shared directory, where the attempts are counted
    backend = open_backend(jobs=1, cluster="local:2", shared_dir=counted)
    prog = run_replicates(reps, counted, backend, poll=0.1)
    assert prog.runs_done == 2, prog.failed
    assert set(prog.failed) == {"fails"} and "breaks for its own reasons" in prog.failed["fails"]
    assert attempts(counted, "dies") == 2 and attempts(counted, "fails") == 1


@pytest.mark.service
def test_a_dead_scheduler_ends_the_experiment_and_resume_continues_it(tmp_path: Path) -> None:
    from coevo.replicates.backends import open_backend
    from coevo.runs.local import free_port

    port = free_port()
    dask = Path(sys.executable).parent / "dask"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).parent)}  # they unpickle this module's functions
    sched = subprocess.Popen([str(dask), "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    worker = subprocess.Popen([str(dask), "worker", f"tcp://127.0.0.1:{port}", "--nthreads", "1", "--no-dashboard"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    try:
        backend = open_backend(jobs=1, cluster=f"tcp://127.0.0.1:{port}")
        backend.client.wait_for_workers(1, timeout=60)
        reps = [job("quick"), job("slow", sleep=120)]
        seen: list[int] = []

        def kill_when_one_is_done(p: object) -> None:
            if p.runs_done == 1 and not seen:  # type: ignore[attr-defined]
                seen.append(1)
                sched.kill()

        t0 = time.monotonic()
        with pytest.raises(ClusterLost, match="lost the Dask scheduler"):
            run_replicates(reps, tmp_path, backend, poll=0.1, on_progress=kill_when_one_is_done)
        assert time.monotonic() - t0 < 60
        assert _finished("quick", tmp_path) and not _finished("slow", tmp_path)
    finally:
        for p in (worker, sched):
            p.kill()
            p.wait()
    again = run_replicates([job("quick"), job("slow")], tmp_path, LocalBackend(1), poll=0.01)  # --resume, anywhere
    assert again.runs_done == 2 and [o.name for o in again.outcomes] == ["slow"]  # the finished one is kept


# ---------------------------------------------------------------- a tiny comparison on Dask
TINY = FINISHED_COMPARISON[1:]  # the session's shared comparison's settings: it is the one made here


def coevo(*args: str, timeout: float = 600) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "coevo", *args], capture_output=True, text=True, timeout=timeout,
                          check=False)


def _form(out: Path) -> tuple[set[str], set[str], list[str]]:
    """What a comparison folder holds, as a form: its files, its runs' files, the keys of results.json."""
    top = {p.name for p in out.iterdir()}
    runs = {str(p.relative_to(r)) for r in (out / "runs").iterdir() for p in r.rglob("*") if "logs" not in p.parts}
    return top, runs, sorted(json.loads((out / "results.json").read_text()))


@pytest.mark.service
@pytest.mark.slow
def test_a_tiny_comparison_on_a_local_dask_cluster_writes_the_report_it_writes_here(finished_comparison: Path,
                                                                                   tmp_path: Path) -> None:
    here, dask = finished_comparison, tmp_path / "dask"  # here: the session's, made by `coevo compare` on this machine
    r = coevo("compare", "--out", str(dask), "--cluster", "local:2", *TINY)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "on the Dask cluster local:2" in r.stdout
    assert _form(here) == _form(dask)
    for f in (here / "settings").iterdir():  # the same seeds give the same per-replicate settings
        assert (dask / "settings" / f.name).read_bytes() == f.read_bytes()
    res = json.loads((dask / "results.json").read_text())
    assert res["runs_finished"] == res["runs_expected"] == 2
    for run in (dask / "runs").iterdir():
        c = coevo_main("check", str(run))  # a reader of files: in this process
        assert c.returncode == 0 and "complete" in c.stdout, c.stdout + c.stderr


@pytest.mark.service
@pytest.mark.slow
def test_the_evolvability_grid_on_a_local_dask_cluster_gives_the_same_curves(tmp_path: Path) -> None:
    import numpy as np

    grid = ["--landscapes", "2", "--runs", "2", "--generations", "20", "--rates", "0.1", "--models", "fm", "gh", "--quiet"]
    for where, flags in (("here", []), ("dask", ["--cluster", "local:2"])):
        r = coevo("evolvability", "--out", str(tmp_path / where), *grid, *flags)
        assert r.returncode == 0, r.stdout + r.stderr
    here, dask = (np.load(tmp_path / w / "curves.npz") for w in ("here", "dask"))
    assert sorted(here.files) == sorted(dask.files)
    for k in here.files:
        assert np.array_equal(here[k], dask[k], equal_nan=True), k


@pytest.mark.service
def test_coevo_seeds_on_a_local_dask_cluster_writes_its_report(tmp_path: Path) -> None:
    tiny = ["--learn-arg=--generations=2", "--learn-arg=--population=4", "--learn-arg=--episodes=4",
            "--learn-arg=--measure-epochs=2", "--quiet"]
    out = tmp_path / "seeds"
    r = coevo("seeds", "--seeds", "1", "--out", str(out), "--cluster", "local:2", *tiny)
    assert r.returncode == 0, r.stdout + r.stderr
    for name in ("report.md", "summary.json", "seeds.csv", "seeds.png"):
        assert (out / name).stat().st_size > 0, name
    res = json.loads((out / "summary.json").read_text())
    assert res["runs_finished"] == res["runs_expected"] == 2
    assert "docking: median docking_from_random_starts" in r.stdout
    again = coevo_main("seeds", "--seeds", "1", "--out", str(out), *tiny)  # a refusal: in this process
    assert again.returncode == 2 and "--resume" in again.stderr


# ---------------------------------------------------------------- across hosts: scheduler and workers in namespaces
def _children(pid: int) -> list[int]:
    r = subprocess.run(["pgrep", "-P", str(pid)], capture_output=True, text=True)
    return [int(x) for x in r.stdout.split()]


@pytest.mark.service
@pytest.mark.slow
def test_a_comparison_across_namespaced_dask_hosts_survives_a_dead_worker(tmp_path: Path) -> None:
    """The scheduler, two Dask workers and the experiment each on a host of their own (a network namespace, one
    LAN): a replicate is a whole run on its worker's loopback, its folder comes back to the experiment over Dask.
    One worker is killed (SIGKILL, as a host that dies) while it runs a replicate: the scheduler gives that
    replicate to the other worker, the comparison completes and every run passes ``coevo check``."""
    from netns import Lab, unavailable

    why = unavailable()
    if why is not None:
        pytest.skip(f"network namespaces unavailable: {why}")
    dask = str(Path(sys.executable).parent / "dask")
    logs, out = tmp_path / "logs", tmp_path / "cmp"
    logs.mkdir()
    with Lab() as lab:
        lab.lan("a")
        for host, addr in (("sched", "10.78.1.1"), ("w1", "10.78.1.11"), ("w2", "10.78.1.12"), ("exp", "10.78.1.20")):
            lab.host(host, a=addr)
        lab.popen("sched", [dask, "scheduler", "--host", "10.78.1.1", "--port", "8786", "--no-dashboard"],
                  log=logs / "sched.log")
        workers = {h: lab.popen(h, [dask, "worker", "tcp://10.78.1.1:8786", "--host", a, "--nthreads", "1",
                                    "--no-nanny", "--no-dashboard"], log=logs / f"{h}.log")
                   for h, a in (("w1", "10.78.1.11"), ("w2", "10.78.1.12"))}
        for h in workers:
            poll(lambda h=h: "Registered to" in (logs / f"{h}.log").read_text(), 60, f"Dask worker {h} registered")
        exp = lab.popen("exp", [sys.executable, "-m", "coevo", "compare", "--out", str(out),
                                "--cluster", "tcp://10.78.1.1:8786", "--runs", "1", "--generations", "8",
                                "--population", "4", "--episodes", "4", "--measure-epochs", "2", "--quiet"],
                        log=logs / "compare.log")

        def busy() -> str | None:  # a worker whose replicate (a coevo run) has been going for a moment
            return next((h for h, p in workers.items() if _children(p.pid)), None)

        victim = poll(busy, 120, "a replicate running on a Dask worker")
        time.sleep(2.0)
        assert exp.poll() is None, (logs / "compare.log").read_text()  # the comparison is still going ...
        assert _children(workers[victim].pid), "the replicate ended before the kill"  # ... and so is the replicate
        workers[victim].kill()
        workers[victim].wait()
        exp.wait(timeout=300)
        text = (logs / "compare.log").read_text()
        assert exp.returncode == 0, text
    res = json.loads((out / "results.json").read_text())
    assert res["runs_finished"] == res["runs_expected"] == 2, text
    for run in (out / "runs").iterdir():
        c = coevo_main("check", str(run))  # a reader of files: in this process
        assert c.returncode == 0 and "complete" in c.stdout, c.stdout + c.stderr
