"""A task from outside coevo, installed for real: examples/coevo-pursuit through every command, as docs/own-task.md
says; plugins that cannot be used, found by name and refused in one line without breaking the others; and the
registry in process (register, lazy imports).

The packages are installed with pip into a folder of their own (``--target``, no build environment, no network)
and put on ``PYTHONPATH`` of the commands started: coevo reads their entry points from the installed metadata, as
it reads its own, and nothing of this environment is changed.
"""

from __future__ import annotations

import fcntl
import json
import os
import re
import shlex
import subprocess
import sys
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "coevo-pursuit"
TUTORIAL = ROOT / "docs" / "own-task.md"
BIN = Path(sys.executable).parent


def _pip_install(target: Path, *sources: str, cwd: Path = ROOT) -> None:
    """``pip install SOURCES`` into ``target``: a real install (wheel built, metadata written), nothing fetched."""
    r = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--disable-pip-version-check", "--no-deps",
                        "--no-build-isolation", "--no-index", "--target", str(target), *sources],
                       cwd=cwd, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr


def _tutorial_commands() -> list[str]:
    """The commands of the tutorial's sh blocks, in order."""
    blocks = re.findall(r"```sh\n(.*?)```", TUTORIAL.read_text(encoding="utf-8"), flags=re.S)
    return [line.strip() for block in blocks for line in block.splitlines() if line.strip()]


@pytest.fixture(scope="session")
def pursuit_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The example installed once per test run, as the tutorial's install command says (shared by the xdist
    workers under a file lock)."""
    shared = tmp_path_factory.getbasetemp().parent
    site = shared / "pursuit-site"
    with open(shared / "pursuit-site.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (site / "coevo_pursuit").exists():
            install = _tutorial_commands()[0]
            assert install == "pip install ./examples/coevo-pursuit", install
            _pip_install(site, *shlex.split(install)[2:])
    return site


def _env(site: Path) -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (str(site), os.environ.get("PYTHONPATH")) if p),
            "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}"}


def _run(argv: list[str], site: Path, cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    exe = {"coevo": [str(BIN / "coevo")], "python": [sys.executable]}[argv[0]]
    return subprocess.run([*exe, *argv[1:]], cwd=cwd, env=_env(site), capture_output=True, text=True, timeout=timeout)


def test_the_installed_example_is_listed_with_its_package_and_passes_the_checker(pursuit_site: Path,
                                                                                tmp_path: Path) -> None:
    r = _run(["coevo", "plugins", "--json"], pursuit_site, tmp_path)
    assert r.returncode == 0, r.stderr
    tasks = {t["name"]: t for t in json.loads(r.stdout)["tasks"]}
    assert tasks["pursuit"]["package"] == "coevo-pursuit 0.1.0" and tasks["pursuit"]["problem"] is None
    assert tasks["pursuit"]["behaviours"] == ["pursuer", "evader"] and tasks["fuel"]["package"].startswith("coevo ")
    checker = next(c for c in _tutorial_commands() if "check_task" in c)
    r = _run(shlex.split(checker), pursuit_site, tmp_path)
    assert r.returncode == 0 and r.stdout.strip() == "the checker finds nothing wrong", r.stdout + r.stderr


def _check_output(command: str, r: subprocess.CompletedProcess[str], cwd: Path, site: Path) -> None:
    """What each of the tutorial's commands must have done, beyond ending with status 0."""
    if command.startswith("coevo learn"):
        out = Path(shlex.split(command)[shlex.split(command).index("--out") + 1])
        assert (cwd / out / "best.rules").exists() and (cwd / out / "best.png").stat().st_size > 1000
        assert re.search(r"measures: captured [\d.]+, escaped [\d.]+", r.stdout), r.stdout
    elif command.startswith("coevo run"):
        assert "final policies together: captured" in r.stdout, r.stdout
    elif command.startswith(("coevo check", "coevo chaos")):
        assert "complete" in r.stdout and "replay exact" in r.stdout, r.stdout
        if "--model hall" in command:  # recorded in the run as it is replayed
            run = cwd / "runs" / shlex.split(command)[shlex.split(command).index("--run") + 1]
            assert json.loads((run / "run.json").read_text())["model"] == "hall"
    elif command.startswith("coevo replay"):
        assert "pursuer: 4 generations reproduced exactly" in r.stdout, r.stdout
    elif command.startswith("coevo status"):
        assert "done" in r.stdout and "pursuer 4/4" in r.stdout and "evader 4/4" in r.stdout, r.stdout
    elif command == "coevo show runs/learn-pursuer --rules":
        assert "pursuer:" in r.stdout and "evader (hand-written):" in r.stdout, r.stdout
    elif command.startswith("coevo show"):
        assert (cwd / "duel.png").stat().st_size > 1000
    elif command.startswith("coevo dynamics"):
        _dynamics_written(cwd / "runs" / "duel" / "dynamics", r.stdout)
    elif command.startswith("coevo study"):
        results = json.loads((cwd / "runs" / "study-pursuer" / "results.json").read_text())
        assert results["runs_finished"] == results["runs_expected"] == 4 and results["behaviour"] == "pursuer"
        assert results["measures"] == ["captured", "escaped", "best_fitness"], results["measures"]
        assert {t["factor"] for t in results["tests"]} == {"ga.mutation_rate"} and "captured" in r.stdout, r.stdout
    elif command.startswith("coevo compare"):
        _comparison_written(cwd / shlex.split(command)[shlex.split(command).index("--out") + 1], r.stdout, site)


@pytest.mark.service
def test_every_command_of_the_tutorial_runs_as_written_on_the_outside_task(pursuit_site: Path, tmp_path: Path) -> None:
    """learn, show, run (a broker and a worker process per behaviour, learning against each other over the bus),
    status, check, replay, chaos: each as docs/own-task.md writes it, after nothing but the package's install."""
    commands = [c for c in _tutorial_commands()[1:] if "check_task" not in c]
    assert len(commands) >= 10, commands
    for command in commands:
        r = _run(shlex.split(command), pursuit_site, tmp_path)
        assert r.returncode == 0 and "Traceback" not in r.stderr, f"{command}: status {r.returncode}\n{r.stderr}"
        _check_output(command, r, tmp_path, pursuit_site)
    _dashboard_shows(pursuit_site, tmp_path)


@pytest.mark.service
def test_the_outside_task_runs_with_a_broker_and_workers_started_by_hand(pursuit_site: Path, tmp_path: Path) -> None:
    """docs/running.md's run by hand on the outside task: ``coevo broker`` and a ``coevo worker`` per behaviour, each
    its own process started by hand, the two sides learning against each other over the bus; then ``coevo status``
    and ``coevo check`` read the run as they read one ``coevo run`` made."""
    from coevo.runs.local import end_processes, free_port, wait_until

    endpoint = f"tcp/127.0.0.1:{free_port()}"
    small = ["--generations", "3", "--population", "6", "--episodes", "10", "--ga", "best_episodes=10",
             "--final-sync", "5"]
    procs: list[subprocess.Popen] = []
    logs = {name: tmp_path / f"{name}.log" for name in ("broker", "pursuer", "evader")}
    try:
        argvs = {"broker": ["broker", "--listen", endpoint, "--data-dir", "runs", "--open"]}
        for seed, b in enumerate(("pursuer", "evader")):
            argvs[b] = ["worker", "--task", "pursuit", "--run", "hand", "--regime", "mutual", "--behaviour", b,
                        "--seed", str(seed), "--connect", endpoint, "--out", f"runs/hand/workers/{b}", *small]
        for name, argv in argvs.items():
            with open(logs[name], "wb") as f:
                procs.append(subprocess.Popen([str(BIN / "coevo"), *argv], cwd=tmp_path, env=_env(pursuit_site),
                                              stdout=f, stderr=subprocess.STDOUT))
        for p, b in zip(procs[1:], ("pursuer", "evader"), strict=True):
            assert p.wait(timeout=240) == 0, logs[b].read_text()
        wait_until(lambda: (tmp_path / "runs" / "hand" / "run.json").exists(), 30, "the workers' run.json")
        status = _run(["coevo", "status", "--run", "hand"], pursuit_site, tmp_path)
        assert status.returncode == 0 and "evader 3/3" in status.stdout and "pursuer 3/3" in status.stdout, status.stdout
    finally:
        end_processes(procs)
    check = _run(["coevo", "check", "runs/hand"], pursuit_site, tmp_path)
    assert check.returncode == 0 and "complete" in check.stdout, check.stdout + check.stderr
    for b in ("pursuer", "evader"):  # each adopted the other's published bests: they learned against each other
        assert (tmp_path / "runs" / "hand" / "workers" / b / "adoptions.jsonl").read_text().strip(), b
    assert "Traceback" not in "".join(f.read_text() for f in logs.values())


def _comparison_written(out: Path, stdout: str, site: Path) -> None:
    """The generic reading of a comparison of the outside task: its measures per regime, the rank tests, a verdict,
    the figures; and the dashboard's model of it (the task's behaviours on its panels, no Table 1)."""
    results = json.loads((out / "results.json").read_text())
    assert results["runs_finished"] == results["runs_expected"] == 4, results
    assert set(results["measures"]) == {"mutual", "independent"}
    assert {"captured", "escaped", "final_pursuer_fitness", "final_evader_fitness"} <= set(results["measures"]["mutual"])
    assert {t["measure"] for t in results["tests"]} >= {"captured", "final_evader_fitness"}
    assert "smoke test" in results["verdict"] and "mutual: captured" in stdout, stdout
    report = (out / "report.md").read_text()
    assert "# Regime comparison: the pursuit task" in report and "| captured |" in report
    for f in ("figure-mutual.png", "figure-independent.png", "regimes.png"):
        assert (out / f).stat().st_size > 1000, f
    probe = ("import json, sys\nfrom pathlib import Path\nfrom coevo.dashboard.compare import ComparisonFiles\n"
             "c = ComparisonFiles(Path(sys.argv[1]), stale=60).read()\n"
             "print(json.dumps({'behaviours': sorted({p['behaviour'] for p in c['panels']}), 'counts': c['counts'], "
             "'classes': c['classes'], 'lines': sum(len(g['lines']) for p in c['panels'] for g in p['groups'].values())}))")
    r = subprocess.run([sys.executable, "-c", probe, str(out)], env=_env(site),
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    seen = json.loads(r.stdout)
    assert seen["behaviours"] == ["evader", "pursuer"] and seen["classes"] == [], seen
    assert seen["counts"]["done"] == 4 and seen["lines"] == 4 * 4, seen  # 4 runs on 4 panels (2 behaviours x 2 curves)


def _dynamics_written(out: Path, stdout: str) -> None:
    """The pursuer's versions against the evader's and back: a CSV cell per pair, its master tournament, pictures."""
    import csv

    for a, b in (("pursuer", "evader"), ("evader", "pursuer")):
        assert f"{a} with {b}:" in stdout, stdout
        ciao = list(csv.DictReader((out / f"ciao-{a}-{b}.csv").open()))
        master = list(csv.DictReader((out / f"master-{a}-{b}.csv").open()))
        assert ciao and len(master) == len(ciao) and [r["version"] for r in ciao] == [r["version"] for r in master]
        cells = [float(v) for r in ciao for k, v in r.items() if k.startswith(f"{b}@")]
        assert cells and all(0.0 <= x <= 1.0 for x in cells)
        row = [float(v) for k, v in ciao[0].items() if k.startswith(f"{b}@")]
        assert abs(float(master[0]["mean"]) - sum(row) / len(row)) < 1e-5  # the master score is the row's mean
        assert (out / f"ciao-{a}-{b}.png").stat().st_size > 1000 and (out / f"master-{a}-{b}.png").stat().st_size > 1000


def _dashboard_shows(site: Path, cwd: Path) -> None:
    """The dashboard's model of the finished run (its task's workers, measures and robot picture), and its page
    served: ``coevo dashboard runs/duel`` as the tutorial says."""
    probe = ("import json, sys\nfrom coevo.dashboard.model import RunFiles\nfrom coevo.dashboard.robot import RobotPanel\n"
             "v = RunFiles(sys.argv[1]).read()\npanel = RobotPanel(sys.argv[1], every=0.0)\npanel.update(now=1.0)\n"
             "print(json.dumps({'task': v.task, 'state': v.state, 'measures': {w['worker']: w['measures'] for w in "
             "v.workers}, 'png': len(panel.picture.png or b''), 'tables': len(panel.picture.tables)}))")
    r = _run(["python", "-c", probe, "runs/duel"], site, cwd)
    assert r.returncode == 0, r.stderr
    seen = json.loads(r.stdout.strip().splitlines()[-1])
    assert seen["task"] == "pursuit" and seen["state"] == "done", seen
    assert set(seen["measures"]) == {"pursuer-0", "evader-1"} and "captured" in seen["measures"]["pursuer-0"], seen
    assert seen["png"] > 1000 and seen["tables"] == 2, seen
    port = 20000 + os.getpid() % 20000
    proc = subprocess.Popen([str(BIN / "coevo"), "dashboard", "runs/duel", "--port", str(port)], cwd=cwd,
                            env=_env(site), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline, page = time.monotonic() + 60, ""
        while time.monotonic() < deadline and proc.poll() is None:
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=5) as resp:
                    page = resp.read().decode()
                break
            except OSError:
                time.sleep(0.3)
        assert "bokeh" in page.lower(), (proc.poll(), page[:300])
    finally:
        proc.terminate()
        out, err = proc.communicate(timeout=30)
    assert "Traceback" not in err, err


# ---------------------------------------------------------------- plugins that cannot be used
_BROKEN = {
    "broken-task": ("broken_task", "broken = \"broken_task:BrokenTask\"", "raise ImportError('needs libfoo, which is not installed')\n"),
    "not-a-task": ("not_a_task", "notatask = \"not_a_task:THING\"", "THING = 42\n"),
    "fuel-clash": ("fuel_clash", "fuel = \"fuel_clash:FuelTask\"", "from coevo.tasks.fuel import FuelTask  # noqa: F401\n"),
}


def _make_package(where: Path, dist: str, module: str, entry: str, code: str) -> Path:
    root = where / dist
    (root / module).mkdir(parents=True)
    (root / module / "__init__.py").write_text(code)
    (root / "pyproject.toml").write_text(
        '[build-system]\nrequires = ["setuptools>=70.1"]\nbuild-backend = "setuptools.build_meta"\n\n'
        f'[project]\nname = "{dist}"\nversion = "0.1.0"\n\n[project.entry-points."coevo.tasks"]\n{entry}\n\n'
        f'[tool.setuptools]\npackages = ["{module}"]\n')
    return root


@pytest.fixture(scope="module")
def broken_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    where = tmp_path_factory.mktemp("broken-plugins")
    site = where / "site"
    _pip_install(site, *[str(_make_package(where, d, *spec)) for d, spec in _BROKEN.items()])
    return site


def test_plugins_that_cannot_be_used_are_one_line_each_naming_the_package_and_break_no_other(
        broken_site: Path, tmp_path: Path) -> None:
    r = _run(["coevo", "plugins"], broken_site, tmp_path)
    assert r.returncode == 1 and "3 plugins cannot be used" in r.stderr, r.stdout + r.stderr
    lines = {line.split()[0]: line for line in r.stdout.splitlines() if line.startswith("  ")}
    assert "broken-task 0.1.0" in lines["broken"] and "ImportError: needs libfoo" in lines["broken"]
    assert "is not a coevo task" in lines["notatask"] and "not-a-task 0.1.0" in lines["notatask"]
    assert "claimed by two packages" in lines["fuel"] and "fuel-clash 0.1.0" in lines["fuel"] and "coevo 0.1.0" in lines["fuel"]
    assert "UNUSABLE" not in lines["door"] and "UNUSABLE" not in lines["corridor"]
    tiny = ["--generations", "1", "--population", "2", "--episodes", "1", "--measure-epochs", "1", "--quiet"]
    r = _run(["coevo", "learn", "--task", "corridor", *tiny, "--out", "ok"], broken_site, tmp_path)
    assert r.returncode == 0, r.stderr  # another task works as before
    for name, says in (("broken", "from broken-task 0.1.0 (broken_task:BrokenTask) cannot be used: ImportError: "
                                  "needs libfoo"),
                       ("notatask", "from not-a-task 0.1.0 (not_a_task:THING) cannot be used"),
                       ("fuel", "is claimed by two packages: coevo 0.1.0 (coevo.tasks.fuel:FuelTask) and fuel-clash "
                                "0.1.0 (fuel_clash:FuelTask)")):
        r = _run(["coevo", "learn", "--task", name, *tiny, "--out", f"no-{name}"], broken_site, tmp_path)
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 2 and len(lines) == 1 and lines[0].startswith("PluginError: ") and says in lines[0], r.stderr
        assert not (tmp_path / f"no-{name}").exists()


# ---------------------------------------------------------------- the registry in process
def test_a_script_registers_a_task_by_object_or_by_name_and_its_module_loads_when_first_named() -> None:
    from coevo.tasks import TASKS, get_task, register_task, task_names
    from coevo.tasks.corridor import CorridorTask

    class Hallway(CorridorTask):
        name = "hallway-test"

    register_task(Hallway)
    register_task("coevo.tasks.corridor:CorridorTask", name="corridor-by-name")
    try:
        assert {"hallway-test", "corridor-by-name"} <= set(task_names())
        assert isinstance(get_task("hallway-test"), Hallway)
        with pytest.raises(Exception, match="installed as 'corridor-by-name' but calls itself 'corridor'"):
            get_task("corridor-by-name")  # the name it is registered under must be its own
        assert "corridor-by-name" in TASKS and TASKS.entry("corridor-by-name").package == "(registered)"
    finally:
        TASKS.unregister("hallway-test")
        TASKS.unregister("corridor-by-name")
    assert "hallway-test" not in task_names()


def test_the_service_and_the_command_line_import_no_task_until_one_is_named() -> None:
    """Importing the CLI, the worker, the broker and coevo status loads no task's package and no CEL module; naming
    a task loads that one only."""
    code = ("import sys\nimport coevo.cli, coevo.agents.worker, coevo.broker.server, coevo.bus.status, coevo.runs.command\n"
            "def loaded():\n    return sorted(m for m in sys.modules if m.startswith(('coevo.tasks.fuel', 'coevo.tasks.door', "
            "'coevo.tasks.corridor', 'coevo.cel')))\nprint(loaded())\nfrom coevo.tasks import get_task\nget_task('corridor')\n"
            "print(loaded())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.splitlines()
    assert out[0] == "[]", out[0]
    assert out[1] == "['coevo.tasks.corridor']", out[1]


def test_a_setting_given_twice_with_two_values_is_one_line_naming_both(tmp_path: Path) -> None:
    from coevo.cli import main

    r = subprocess.run([str(BIN / "coevo"), "learn", "--behaviour", "corridor", "--population", "2", "--ga",
                        "population=1e309", "--quiet", "--out", str(tmp_path / "x")], capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.strip() == ("ConfigError: --population 2 and --ga population=1e309 disagree: "
                                                      "give population once"), r.stderr
    assert not (tmp_path / "x").exists()
    assert main(["learn", "--behaviour", "corridor", "--population", "2", "--ga", "population=2", "--generations", "1",
                 "--episodes", "1", "--measure-epochs", "1", "--quiet", "--out", str(tmp_path / "y")]) == 0


@pytest.fixture(autouse=True)
def _no_leftover_registrations() -> Iterator[None]:
    yield
    from coevo.tasks import TASKS

    assert not [n for n in TASKS.names() if n.endswith("-test") or n.endswith("-by-name")]
