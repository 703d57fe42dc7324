"""`lagrange sweep` and `System.sweep`: grids, samples, measures, sections, failures, resume, Dask."""

from __future__ import annotations

import csv
import itertools
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from lagrange_cli import derive, spec
from lagrange_cli import sweep as library
from lagrange_cli.cli import app
from lagrange_cli.sweep import Axis, points

ROOT = Path(__file__).resolve().parent.parent


def model(name: str):  # type: ignore[no-untyped-def]
    return derive.derive(spec.load(spec.resolve(name)))


def run(*arguments: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(app, ["sweep", *arguments])
    return result.exit_code, result.stdout, result.stderr


def rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as handle:
        return list(csv.DictReader(handle))


# -- points ------------------------------------------------------------------------------------------


def test_grid_is_every_combination_last_axis_fastest() -> None:
    grid = points([Axis("set", "k", 1, 3, 3), Axis("initial", "x", 0, 1, 2)])
    assert grid.tolist() == [[1, 0], [1, 1], [2, 0], [2, 1], [3, 0], [3, 1]]


def test_log_spacing_is_geometric() -> None:
    assert np.allclose(points([Axis("set", "g", 1, 100, 3, log=True)])[:, 0], [1, 10, 100])
    code, out, _ = run("simple_pendulum", "--set", "g=1..100:3:log", "-q")
    assert code == 0
    assert [float(r["g"]) for r in csv.DictReader(out.splitlines())] == pytest.approx([1, 10, 100])


def test_sample_is_seeded_and_inside_the_ranges() -> None:
    axes = [Axis("set", "g", 1, 100, log=True), Axis("initial", "theta", -1, 1)]
    first, again, other = points(axes, 50, seed=3), points(axes, 50, seed=3), points(axes, 50, seed=4)
    assert np.array_equal(first, again) and not np.array_equal(first, other)
    assert first[:, 0].min() >= 1 and first[:, 0].max() <= 100 and np.abs(first[:, 1]).max() <= 1


# -- measures ----------------------------------------------------------------------------------------


def test_measures_of_a_small_pendulum() -> None:
    """Small swings: max(theta) is the amplitude, the period 2 pi sqrt(l/g), the energy error small."""
    pendulum = model("simple_pendulum")
    table = library.sweep(pendulum, [Axis("initial", "theta", 0.01, 0.02, 2)], measures=["max(theta)", "period", "energy_error", "final", "l*theta_dot"], t_end=10, rtol=1e-9, atol=1e-12)
    values = dict(pendulum.initial)
    g, length = (next(p.value for p in pendulum.parameters if p.name == name) for name in ("g", "l"))
    assert table.column("max(theta)") == pytest.approx([0.01, 0.02], rel=1e-6)
    assert table.column("period") == pytest.approx(2 * math.pi * math.sqrt(length / g), rel=1e-3)
    assert max(table.column("energy_error")) < 1e-7
    assert table.column("l*theta_dot") == pytest.approx(length * table.column("theta_dot_final"))
    assert values is not None


def test_lyapunov_separates_regular_from_chaotic_motion() -> None:
    pendulum = model("double_pendulum")
    table = library.sweep(pendulum, [Axis("initial", "theta", 0.05, 2.0, 2)], measures=["lyapunov"], initial={"phi": 0.0}, t_end=20, rtol=1e-9)
    small, large = table.column("lyapunov")
    assert small < 0.3 < large


def test_event_time_of_the_until_condition() -> None:
    """A pendulum released at rest from theta0 passes theta = 0 after a quarter period."""
    pendulum = model("simple_pendulum")
    table = library.sweep(pendulum, [Axis("initial", "theta", 0.01, 0.01, 1)], until="theta", t_end=10, rtol=1e-10, atol=1e-12)
    g, length = (next(p.value for p in pendulum.parameters if p.name == name) for name in ("g", "l"))
    assert table.column("t_event")[0] == pytest.approx(math.pi / 2 * math.sqrt(length / g), rel=1e-4)
    assert table.column("status")[0] == "event"


def test_poincare_section_lies_on_the_energy_level() -> None:
    """Crossings of theta = 0 upwards of a pendulum released from theta0: all at
    theta_dot = sqrt(2 g / l (1 - cos theta0)), the invariant curve of its energy."""
    pendulum = model("simple_pendulum")
    g, length = (next(p.value for p in pendulum.parameters if p.name == name) for name in ("g", "l"))
    table = library.sweep(pendulum, [Axis("initial", "theta", 0.5, 2.5, 3)], section="theta=0, theta_dot>0", t_end=30, rtol=1e-10, atol=1e-12)
    crossing = table.column("crossing")
    assert (crossing > 0).all()
    for start in (0.5, 1.5, 2.5):
        mine = [row for row in table.rows if row[1] == start]
        assert len(mine) >= 3
        speeds = [row[table.columns.index("theta_dot")] for row in mine]
        assert speeds == pytest.approx([math.sqrt(2 * g / length * (1 - math.cos(start)))] * len(mine), rel=1e-7)
        assert all(abs(row[table.columns.index("theta")]) < 1e-9 for row in mine)
        times = [row[table.columns.index("t")] for row in mine]
        assert times == sorted(times)


def test_section_direction_is_kept() -> None:
    pendulum = model("simple_pendulum")
    up = library.sweep(pendulum, [Axis("initial", "theta", 1, 1, 1)], section="theta=0, theta_dot>0", t_end=20)
    down = library.sweep(pendulum, [Axis("initial", "theta", 1, 1, 1)], section="theta=0, theta_dot<0", t_end=20)
    assert (up.column("theta_dot") > 0).all() and (down.column("theta_dot") < 0).all()


def test_failed_runs_are_rows_with_their_reason(tmp_path: Path) -> None:
    """Zero angular momentum: the Kepler orbit falls into r = 0 and that run fails; the others finish."""
    out = tmp_path / "kepler.csv"
    code, _, err = run("kepler", "--initial", "theta_dot=0..1.2:3", "--measure", "energy_error", "-o", str(out), "-q")
    assert code == 0, err
    found = rows(out)
    assert [r["status"] for r in found] == ["failed", "finished", "finished"]
    assert "failed at t =" in found[0]["reason"] and "r =" in found[0]["reason"]
    assert found[0]["energy_error"] == "nan" and float(found[1]["energy_error"]) < 1e-6
    assert "1 failed" in err


def test_the_heap_is_frozen_during_a_sweep_and_thawed_after() -> None:
    """During a sweep the objects made before it are out of the garbage collector's full collections (`gc.freeze`; a
    full collection traverses the whole heap with the GIL held, stalling an in-process Dask scheduler), and they are
    back after it, also when the sweep fails; a heap someone else froze is left frozen as it was."""
    import gc

    pendulum = model("simple_pendulum")
    axes = [Axis("set", "g", 1, 2, 4)]
    gc.collect()
    objects = len(gc.get_objects())
    frozen: list[int] = []
    assert gc.get_freeze_count() == 0
    library.sweep(pendulum, axes, t_end=1, batch=1, on_batch=lambda rows, done, total: frozen.append(gc.get_freeze_count()))
    assert len(frozen) == 4 and min(frozen) >= objects and gc.get_freeze_count() == 0

    def fail(rows: list, done: int, total: int) -> None:  # type: ignore[type-arg]
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        library.sweep(pendulum, axes, t_end=1, batch=1, on_batch=fail)
    assert gc.get_freeze_count() == 0
    gc.freeze()
    try:
        theirs = gc.get_freeze_count()
        library.sweep(pendulum, axes, t_end=1, batch=1)
        assert gc.get_freeze_count() == theirs
    finally:
        gc.unfreeze()


def test_threads_give_the_results_of_one_worker() -> None:
    pendulum = model("double_pendulum")
    axes = [Axis("initial", "theta", -2, 2, 4), Axis("initial", "phi", -2, 2, 3)]
    one = library.sweep(pendulum, axes, measures=["final", "max(phi)"], t_end=3, batch=2)
    two = library.sweep(pendulum, axes, measures=["final", "max(phi)"], t_end=3, batch=2, workers=2)
    assert one.rows == two.rows and [r[0] for r in one.rows] == list(range(12))


def test_local_sweeps_run_a_group_of_batches_in_one_compiled_call() -> None:
    """One worker and --workers 2 group consecutive batches as the Dask tasks do (`_task_groups`) and run a group's runs
    in one compiled call (the lanes refilled across its batches): fewer calls and fewer lane evaluations (idle lanes at
    the end of each call) than a call per batch, the same rows bit for bit, every batch delivered once, in order."""
    pendulum = model("double_pendulum")
    axes = [Axis("initial", "theta", -2, 2, 20), Axis("initial", "phi", -2, 2, 15)]  # 300 points, 12 batches of 25
    options = {"measures": ["final"], "t_end": 2, "batch": 25}
    library.sweep(pendulum, axes, **{**options, "batch": 300})
    runner = next(r for r in library._RUNNERS.values() if r.model is pendulum and r.job.measures == ("final",) and dict(r.job.options) == {"t_end": 2})
    entry = runner.lanes_entry
    assert entry is not None
    grid = points(axes)
    batches = [list(range(k, k + 25)) for k in range(0, 300, 25)]
    counts = {"calls": 0, "evaluations": 0}

    def counted(*arguments):  # type: ignore[no-untyped-def]
        result = entry(*arguments)
        counts["calls"] += 1  # the GIL is held here: the threads' counts do not race
        counts["evaluations"] += int(result[5])
        return result

    runner.lanes_entry = counted
    try:
        per_batch = [row for b in batches for row in runner.batch(b, grid[b])]  # a compiled call per batch, as before
        before = dict(counts)
        seen: dict[int, list[tuple[int, int]]] = {}
        found = {}
        for workers in (1, 2):
            counts.update(calls=0, evaluations=0)
            delivered = seen.setdefault(workers, [])
            table = library.sweep(pendulum, axes, workers=workers, on_batch=lambda rows, done, total, d=delivered: d.append((len(rows), done)), **options)
            found[workers] = dict(counts)
            assert repr(table.rows) == repr(per_batch)
            assert delivered == [(25, 25 * (k + 1)) for k in range(12)]
    finally:
        runner.lanes_entry = entry
    assert before["calls"] == 12
    assert [len(g) for g in library._task_groups(batches, 1)] == [6, 3, 2, 1]
    assert found[1]["calls"] == 4 and found[1]["evaluations"] < before["evaluations"]
    assert [len(g) for g in library._task_groups(batches, 2)] == [3, 3, 2, 1, 1, 1, 1]  # 2 threads: a call a group
    assert found[2]["calls"] == 7 and found[2]["evaluations"] < before["evaluations"]


# -- resume --------------------------------------------------------------------------------------------


def test_resume_after_an_interruption(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    arguments = ["double_pendulum", "--initial", "theta=-2..2:5", "--initial", "phi=0..1:3", "--t-end", "2", "--batch", "2", "-q"]
    whole = tmp_path / "whole.csv"
    assert run(*arguments, "-o", str(whole))[0] == 0
    out = tmp_path / "part.csv"
    journal = tmp_path / "part.csv.partial.csv"
    interrupt_after(monkeypatch, 4)  # the header, then 3 batches, then stop
    code, _, err = run(*arguments, "-o", str(out))
    assert code == 130 and "--resume" in err
    lines = journal.read_text().splitlines()
    assert not out.exists() and lines[0].startswith("# lagrange sweep ") and lines[1].startswith("index,") and len(lines) == 2 + 6
    with journal.open("a") as handle:
        handle.write("6,0.0,0.")  # a line cut by the interruption
    monkeypatch.undo()
    code, _, err = run(*arguments, "-o", str(out), "--resume")
    assert code == 0, err
    assert out.read_text() == whole.read_text() and not journal.exists()
    assert [int(r["index"]) for r in rows(out)] == list(range(15))


def interrupt_after(monkeypatch: pytest.MonkeyPatch, writes: int) -> None:
    """The next sweep stops (as by Ctrl-C) after `writes` writes to its journal (the first is the header)."""
    real, calls = library.append_rows, []

    def interrupted(*arguments, **options) -> None:  # type: ignore[no-untyped-def]
        calls.append(1)
        if len(calls) > writes:
            raise KeyboardInterrupt
        real(*arguments, **options)

    monkeypatch.setattr(library, "append_rows", interrupted)


@pytest.mark.parametrize("other", [["--initial", "theta=0..1:5"], ["--initial", "theta=0..1:4", "--t-end", "3"], ["--initial", "theta=0..1:4", "--measure", "max(theta)"]])
def test_resume_refuses_another_sweeps_journal(other: list[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "t.csv"
    with monkeypatch.context() as patch:
        interrupt_after(patch, 2)
        assert run("simple_pendulum", "--initial", "theta=0..1:4", "--batch", "1", "-o", str(out), "-q")[0] == 130
    code, _, err = run("simple_pendulum", *other, "--batch", "1", "-o", str(out), "--resume", "-q")
    assert code == 2 and "another sweep" in err, err
    assert run("simple_pendulum", "--initial", "theta=0..1:4", "--batch", "1", "-o", str(out), "--resume", "-q")[0] == 0
    assert [int(r["index"]) for r in rows(out)] == [0, 1, 2, 3]


# -- bad options ------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("arguments", "expected"),
    [
        (["--set", "g=1..3"], "needs a count"),
        (["--set", "g=0..3:4:log"], "log spacing of 'g' needs a positive range"),
        (["--set", "g=1..3:4:cubic"], "unknown spacing"),
        (["--set", "g=1..3:x"], "count of 'g' must be a whole number"),
        (["--set", "gg=1..3:3"], "did you mean 'g'"),
        (["--set", "g=1..3:3", "--measure", "max(foo)"], "unknown name 'foo'"),
        (["--set", "g=1..3:3", "--measure", "t_event"], "needs --until"),
        (["--set", "g=1..3:3", "--section", "theta<0"], "one equation"),
        (["--set", "g=1..3:3", "--section", "theta=0, theta_dot"], "not a condition"),
        (["--set", "g=1..3:3", "--section", "theta=0", "--until", "theta"], "give one of them"),
        (["--set", "g=1..3:3", "--sample", "5"], "without a count"),
        (["--set", "g=1..3:3", "--workers", "0"], "--workers"),
        (["--set", "g=1..3:3", "--resume"], "give -o"),
        (["--set", "g=1..3:3", "-o", "x.txt"], ".csv, .parquet"),
        (["--set", "m=-1..3:3"], "'m' is positive"),
        ([], "nothing to sweep"),
    ],
)
def test_bad_options_exit_2_saying_what_was_expected(arguments: list[str], expected: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    code, out, err = run("simple_pendulum", *arguments, "-q")
    assert code == 2, (out, err)
    assert expected in err and "Traceback" not in err
    assert not list(tmp_path.iterdir())  # nothing written


# -- API ------------------------------------------------------------------------------------------------------


def test_system_sweep() -> None:
    from lagrange_cli.api import load

    system = load("simple_pendulum")
    table = system.sweep(initial={"theta": (0.1, 0.2, 2)}, parameters={"g": 9.81}, measures=["max(theta)"], t_end=2)
    plain = table if isinstance(table, library.Table) else None
    if plain is None:
        assert list(table["max(theta)"]) == pytest.approx([0.1, 0.2])
    else:
        assert plain.column("max(theta)") == pytest.approx([0.1, 0.2])


# -- Dask ----------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def cluster():  # type: ignore[no-untyped-def]
    """Two worker processes of one thread each (the machine's two cores)."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as local:  # any free port: another test process may hold 8787
        yield local
        library.close_clients()  # the sweeps' kept client, before its scheduler goes


DASK_AXES = [Axis("initial", "theta", -2, 2, 4), Axis("initial", "phi", -2, 2, 3)]


def test_dask_cluster_gives_exactly_the_local_results(cluster, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    arguments = ["double_pendulum", "--initial", "theta=-2..2:4", "--initial", "phi=-2..2:3", "--t-end", "3", "--measure", "final", "--measure", "max(phi)", "--batch", "1", "-q"]
    local, remote = tmp_path / "local.csv", tmp_path / "remote.csv"
    assert run(*arguments, "-o", str(local))[0] == 0
    code, _, err = run(*arguments, "-o", str(remote), "--scheduler", cluster.scheduler_address)
    assert code == 0, err
    assert remote.read_text() == local.read_text() and len(rows(remote)) == 12


def test_dask_tasks_carry_consecutive_batches_large_first() -> None:
    batches = [[k] for k in range(40)]
    groups = library._task_groups(batches, 2)  # 40 batches, 2 workers: each task a quarter of the batches left
    assert [b for group in groups for b in group] == batches
    assert [len(g) for g in groups] == [10, 8, 6, 4, 3, 3, 2, 1, 1, 1, 1]
    assert library._task_groups(batches[:3], 2) == [[b] for b in batches[:3]]  # never fewer than one batch a task
    assert len(library._task_groups([[k] for k in range(10**5)], 1)[0]) == library.MAX_BATCHES_PER_TASK


def test_rows_from_arrays_are_the_run_by_run_rows() -> None:
    """A batch whose measures are read off the runs' ends (final, t_event) makes its rows from the compiled call's
    arrays (Runner.ended / Runner.rows, what a Dask task sends back): the rows of the general path (Runner._measured_batch,
    an Outcome and measured_rows per run) bit for bit, failed runs (a singular mass matrix at x = -1) and events included,
    in lanes and in the run-by-run batch (an event)."""
    elastic = model("elastic_pendulum")
    axes = [Axis("initial", "x", -1.0, 0.3, 3), Axis("initial", "theta", 0.2, 1.4, 4)]
    for extra in ({"measures": ["final"]}, {"measures": ["t_event", "final"], "until": "theta"}):
        options = {"t_end": 5, "rtol": 1e-9, "method": "DOP853", "backend": "compiled", "batch": 5, **extra}
        table = library.sweep(elastic, axes, **options)
        runner = next(r for r in library._RUNNERS.values() if r.model is elastic and r.job.measures == tuple(extra["measures"]) and dict(r.job.options).get("until") == extra.get("until"))
        assert runner.plain and (runner.lanes_entry is None) == ("until" in extra)  # lanes; an event: ensemble.batch
        grid = library.points(axes)
        ended = runner.ended(list(range(len(grid))), grid)
        assert isinstance(ended, library.Ended)
        general = runner._measured_batch(list(range(len(grid))), grid)
        assert repr(runner.rows(ended)) == repr(general) == repr(table.rows)  # bit for bit (NaN included)
        status = table.column("status").tolist()
        assert status[:4] == ["failed"] * 4 and "singular" in table.rows[0][table.columns.index("reason")]
        assert set(status[4:]) == ({"event"} if "until" in extra else {"finished"})


def test_a_dask_task_runs_its_batches_in_one_compiled_call() -> None:
    """A task of several batches whose measures are read off the runs' ends runs them in one compiled call (the lanes
    refilled across its batches) and sends back how its runs ended as three arrays (status codes, last times, last
    states: 8 + 8 + 8 x 4 bytes a run, not the indices and points it was sent); each batch's share of the Ended the
    client makes of them gives that batch's local rows. With another measure (max), the task sends back each batch's
    rows, as a thread would make them."""
    import pickle

    pendulum = model("double_pendulum")
    axes = [Axis("initial", "theta", -2, 2, 5), Axis("initial", "phi", -2, 2, 4)]  # 20 points
    grid = points(axes)
    sizes = [6, 6, 6, 2]
    indices = np.arange(len(grid), dtype=np.int64)
    for measures in (["final"], ["final", "max(phi)"]):
        local = library.sweep(pendulum, axes, measures=measures, t_end=2, batch=6)
        job = library.Job(library._source_text(pendulum), pendulum.source, tuple(axes), tuple(measures), None, (("t_end", 2),))
        runner = library.runner_for(job)
        calls = [0]
        entry = runner.lanes_entry
        assert entry is not None

        def counted(*arguments, entry=entry, calls=calls):  # type: ignore[no-untyped-def]
            calls[0] += 1
            return entry(*arguments)

        runner.lanes_entry = counted
        try:
            result = library._dask_task(indices, grid[indices], sizes, job)
        finally:
            runner.lanes_entry = entry
        if measures == ["final"]:
            assert isinstance(result, tuple) and calls[0] == 1
            codes, t_last, y_last = result
            assert codes.shape == t_last.shape == (20,) and y_last.shape == (20, 4)
            assert sum(a.nbytes for a in result) == 20 * (8 + 8 + 8 * 4) and len(pickle.dumps(result, protocol=5)) < 20 * 48 + 600
            result = library.Ended(indices, grid[indices], *result)
            bounds = [0, 6, 12, 18, 20]
            batches = [runner.rows(result.part(a, b)) for a, b in itertools.pairwise(bounds)]
        else:
            assert isinstance(result, list) and calls[0] == len(sizes)
            batches = result
        assert [len(b) for b in batches] == sizes and [row for b in batches for row in b] == local.rows


def test_dask_tasks_of_several_batches_give_the_local_rows(cluster) -> None:  # type: ignore[no-untyped-def]
    pendulum = model("double_pendulum")
    axes = [Axis("initial", "theta", -2, 2, 8), Axis("initial", "phi", -2, 2, 5)]  # 40 batches of 1: tasks of 5
    seen: list[int] = []
    local = library.sweep(pendulum, axes, measures=["final"], t_end=1, batch=1)
    remote = library.sweep(pendulum, axes, measures=["final"], t_end=1, batch=1, scheduler=cluster.scheduler_address, on_batch=lambda rows, done, total: seen.append(done))
    assert remote.rows == local.rows and seen == list(range(1, 41))  # every batch delivered on its own, in order


def test_a_dask_sweep_sends_its_tasks_in_one_graph(cluster) -> None:  # type: ignore[no-untyped-def]
    """All the tasks of a sweep reach the scheduler in one message (`update_graph`, counted by a scheduler plugin): it
    hands every worker its first task at once, and the job is pickled once; there are as many tasks as `_task_groups`
    makes (consecutive batches, large first), and every worker that has built the system is not asked again."""
    from distributed import Client
    from distributed.diagnostics.plugin import SchedulerPlugin

    class Graphs(SchedulerPlugin):
        name = "test-sweep-graphs"

        def __init__(self) -> None:
            self.calls: list[int] = []

        def update_graph(self, scheduler, *, keys=(), **kwargs) -> None:  # type: ignore[no-untyped-def]
            self.calls.append(len(keys))

    pendulum = model("double_pendulum")
    axes = [Axis("initial", "theta", -2, 2, 8), Axis("initial", "phi", -2, 2, 5)]  # 40 points, batches of 2: 20 batches
    with Client(cluster.scheduler_address, set_as_default=False) as client:
        client.wait_for_workers(2)
    library.sweep(pendulum, axes, measures=["final"], t_end=0.5, batch=2, scheduler=cluster.scheduler_address)  # the workers build the system
    graphs = Graphs()
    cluster.scheduler.add_plugin(graphs)
    try:
        remote = library.sweep(pendulum, axes, measures=["final"], t_end=0.5, batch=2, scheduler=cluster.scheduler_address)
    finally:
        cluster.scheduler.remove_plugin(name=graphs.name)
    groups = library._task_groups([[2 * k, 2 * k + 1] for k in range(20)], 2)
    assert graphs.calls == [len(groups)] and len(groups) == 9
    assert remote.rows == library.sweep(pendulum, axes, measures=["final"], t_end=0.5, batch=2).rows


def test_a_killed_worker_loses_no_rows(cluster) -> None:  # type: ignore[no-untyped-def]
    """After the first batch one worker process is killed (SIGKILL): Dask reruns its tasks on the
    other (and on the worker its nanny restarts); every row arrives, equal to the local run's."""
    import os
    import signal

    from distributed import Client

    pendulum = model("double_pendulum")
    local = library.sweep(pendulum, DASK_AXES, measures=["final"], t_end=3, batch=1)
    killed: list[str] = []

    def kill_one(batch: list, done: int, total: int) -> None:  # type: ignore[type-arg]
        if not killed:
            with Client(cluster.scheduler_address) as client:
                victim = sorted(client.scheduler_info()["workers"])[0]
                os.kill(client.run(os.getpid)[victim], signal.SIGKILL)
                killed.append(victim)

    remote = library.sweep(pendulum, DASK_AXES, measures=["final"], t_end=3, batch=1, scheduler=cluster.scheduler_address, on_batch=kill_one)
    assert killed and remote.rows == local.rows
    assert [row[0] for row in remote.rows] == list(range(12))


def _built_on_worker(key: str) -> bool:
    return key in library._RUNNERS


def test_every_dask_worker_builds_the_system_once_even_for_one_batch(cluster) -> None:  # type: ignore[no-untyped-def]
    """A sweep of one batch has every worker build the system (ahead of the batches), so that the next sweep
    of the session pays no worker's derivation and loading: it was the Dask path's extra cost in the benchmark."""
    from distributed import Client

    pendulum = model("double_pendulum")
    options = {"measures": ["final", "max(theta)"], "t_end": 2.5}
    with Client(cluster.scheduler_address, set_as_default=False) as client:
        client.wait_for_workers(2)  # a worker killed by the test above is restarted by its nanny
        table = library.sweep(pendulum, DASK_AXES[:1], scheduler=cluster.scheduler_address, **options)
        assert len(table) == 4
        key = next(k for k, r in library._RUNNERS.items() if r.model is pendulum and r.job.measures == ("final", "max(theta)"))
        built = client.run(_built_on_worker, key)
    assert len(built) == 2 and all(built.values())


def test_dask_client_is_kept_and_a_lost_scheduler_is_a_clean_error() -> None:
    """The client of a scheduler is kept for the next sweep of the process (no connect and close per sweep); when the
    scheduler goes away, the next sweep says it cannot connect (a LagrangeError), and the kept client is dropped."""
    distributed = pytest.importorskip("distributed")
    pendulum = model("simple_pendulum")
    axes = [Axis("set", "g", 1, 2, 3)]
    local = library.sweep(pendulum, axes, t_end=1)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0") as cluster:
        address = cluster.scheduler_address
        assert library.sweep(pendulum, axes, t_end=1, scheduler=address).rows == local.rows
        kept = library._CLIENTS[address]
        assert library.sweep(pendulum, axes, t_end=1, scheduler=address).rows == local.rows and library._CLIENTS[address] is kept
    old = library.CONNECT_TIMEOUT
    library.CONNECT_TIMEOUT = 1
    try:
        with pytest.raises(library.LagrangeError, match=f"--scheduler {address}: "):
            library.sweep(pendulum, axes, t_end=1, scheduler=address)
    finally:
        library.CONNECT_TIMEOUT = old
    assert address not in library._CLIENTS and kept.status != "running"


def test_dask_is_imported_only_for_a_scheduler(tmp_path: Path) -> None:
    import subprocess
    import sys

    code = "import sys; from typer.testing import CliRunner; from lagrange_cli.cli import app; r = CliRunner().invoke(app, ['sweep', 'simple_pendulum', '--set', 'g=1..2:2', '-q']); assert r.exit_code == 0, r.output; print('distributed' in sys.modules or 'dask' in sys.modules)"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=tmp_path, env={**__import__("os").environ, "PYTHONPATH": str(ROOT)})
    assert result.stdout.strip() == "False"


def test_unreachable_scheduler_exits_2(monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("distributed")
    monkeypatch.setattr(library, "CONNECT_TIMEOUT", 1)
    code, _, err = run("simple_pendulum", "--set", "g=1..2:2", "--scheduler", "tcp://127.0.0.1:9", "-q")
    assert code == 2 and "cannot connect" in err


@pytest.mark.parametrize(
    "arguments",
    [
        ["--set", "g=1..20:4:log", "--measure", "max(theta)"],
        ["--set", "g=5..20:3", "--initial", "theta=0.1..1:3", "--measure", "period"],
        ["--set", "g=5..20", "--initial", "theta=0.1..1", "--sample", "6", "--measure", "period"],
        ["--initial", "theta=0.5..1:2", "--section", "theta=0, theta_dot>0"],
    ],
    ids=["line", "heat-map", "sample-scatter", "section-scatter"],
)
def test_plots_fit_the_sweep(arguments: list[str], tmp_path: Path) -> None:
    picture = tmp_path / "sweep.png"
    code, _, err = run("simple_pendulum", *arguments, "--t-end", "5", "--plot", str(picture), "-q")
    assert code == 0, err
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_parquet_needs_pyarrow_or_is_written(tmp_path: Path) -> None:
    import importlib.util

    out = tmp_path / "t.parquet"
    code, _, err = run("simple_pendulum", "--set", "g=1..2:2", "-o", str(out), "-q")
    if importlib.util.find_spec("pyarrow") is None:
        assert code == 2 and "pyarrow" in err and not out.exists()
    else:
        import pyarrow.parquet as pq

        assert code == 0 and pq.read_table(str(out)).column("g").to_pylist() == [1.0, 2.0]


def test_lyapunov_is_measured_for_a_whole_batch_at_once(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """The compiled path measures the Lyapunov exponents of a batch with one compiled call per
    segment (Runner.lyapunov_batch), never run by run from Python, and gets the per-run values."""
    pendulum = model("double_pendulum")
    axes = [Axis("initial", "theta", 0.05, 2.0, 3)]
    options = {"measures": ["lyapunov"], "initial": {"phi": 0.0}, "t_end": 5, "rtol": 1e-9, "method": "DOP853", "backend": "compiled"}
    table = library.sweep(pendulum, axes, **options)
    runner = next(r for r in library._RUNNERS.values() if r.model is pendulum and r.job.measures == ("lyapunov",))
    one_by_one = [runner._lyapunov(*runner.point(values)) for values in library.points(axes)]
    assert np.array_equal(np.array(table.column("lyapunov")), np.array(one_by_one))

    def refuse(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise AssertionError("a run's exponent was measured on its own")

    monkeypatch.setattr(library.Runner, "_lyapunov", refuse)
    again = library.sweep(pendulum, axes, **{**options, "t_end": 5.0})
    assert np.array_equal(np.array(again.column("lyapunov")), np.array(one_by_one))


def test_section_is_run_for_a_whole_batch_at_once(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """A Poincare section on the compiled path runs its batch in one compiled call (Runner.section_batch,
    every crossing recorded there) and gets exactly the rows of the run-by-run path (Runner._erk from
    Python, restarted at each crossing): the same crossings, times and states, a failed run's reason, and
    the same cut at MAX_CROSSINGS."""
    elastic = model("elastic_pendulum")
    axes = [Axis("initial", "x", -1.0, 0.3, 2), Axis("initial", "theta", 0.2, 1.4, 4)]  # x = -1: l + x = 0, a singular mass matrix
    options = {"section": "theta=0, theta_dot>0", "t_end": 40, "rtol": 1e-9, "method": "DOP853", "backend": "compiled", "batch": 3}
    table = library.sweep(elastic, axes, **options)
    runner = next(r for r in library._RUNNERS.values() if r.model is elastic and r.job.section == options["section"])

    def one_by_one() -> list[list[object]]:
        return [row for k, values in enumerate(library.points(axes)) for row in runner.run_point(k, values)]

    assert table.rows and repr(table.rows) == repr(one_by_one())  # bit for bit (NaN included)
    status = table.column("status").tolist()
    assert status[:4] == ["failed"] * 4 and "singular" in table.rows[0][table.columns.index("reason")]
    assert set(status[4:]) == {"finished"} and max(table.column("crossing")) >= 5

    monkeypatch.setattr(library, "MAX_CROSSINGS", 3)  # each run ends at its 4th crossing, in both paths
    cut = library.sweep(elastic, axes, **options)
    assert repr(cut.rows) == repr(one_by_one()) and max(cut.column("crossing")) <= 2  # 3 crossings alternate up and down

    def refuse(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise AssertionError("a section's run was integrated on its own")

    monkeypatch.setattr(library.Runner, "_erk", refuse)
    assert repr(library.sweep(elastic, axes, **options).rows) == repr(cut.rows)
