"""Hostile outputs: a run folder is written whole or not at all, never merged, never shared by two runs."""

from __future__ import annotations

import json
import os
import stat

import pytest

from lost.host import runfolder
from lost.host.cli import EXIT_ERROR, EXIT_INTERRUPTED, EXIT_OK
from lost.host.runfolder import run_folder


def _files(folder):
    return sorted(p.name for p in folder.iterdir())


def test_a_run_lands_whole_and_leaves_no_temporary_folder(tiny, tmp_path, run_cli):
    out = tmp_path / "runs" / "a"
    code, printed, _ = run_cli("run", tiny, "--out", out)
    assert code == EXIT_OK
    assert {"track.csv", "summary.json", "map.png"} <= set(_files(out))
    assert [p.name for p in out.parent.iterdir()] == ["a"]  # no .partial, .old or .lock left beside it
    assert stat.S_IMODE(out.stat().st_mode) & 0o055  # an ordinary folder, not mkdtemp's private one


def test_a_second_run_into_a_run_folder_is_refused(tiny, tmp_path, run_cli):
    out = tmp_path / "a"
    assert run_cli("run", tiny, "--out", out)[0] == EXIT_OK
    before = (out / "track.csv").read_bytes()
    code, _, err = run_cli("run", tiny, "--out", out)
    assert code == EXIT_ERROR and "already holds a run; pass --replace" in err
    assert (out / "track.csv").read_bytes() == before


def test_replace_replaces_the_whole_folder_no_stale_file_survives(tiny, tmp_path, run_cli):
    out = tmp_path / "a"
    assert run_cli("run", tiny, "--out", out)[0] == EXIT_OK
    (out / "error_from_an_older_run.png").write_bytes(b"old")
    assert run_cli("run", tiny, "--out", out, "--replace")[0] == EXIT_OK
    assert "error_from_an_older_run.png" not in _files(out)
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_a_non_empty_folder_that_is_no_run_is_refused_even_with_replace(tiny, tmp_path, run_cli):
    out = tmp_path / "thesis"
    out.mkdir()
    (out / "chapter1.tex").write_text("precious")
    code, _, err = run_cli("run", tiny, "--out", out, "--replace")
    assert code == EXIT_ERROR and "holds no LOST run" in err
    assert (out / "chapter1.tex").read_text() == "precious"


def test_an_empty_existing_folder_is_used(tiny, tmp_path, run_cli):
    out = tmp_path / "empty"
    out.mkdir()
    assert run_cli("run", tiny, "--out", out)[0] == EXIT_OK
    assert (out / "summary.json").is_file()


def test_out_naming_a_file_is_refused(tiny, tmp_path, run_cli):
    out = tmp_path / "notes.txt"
    out.write_text("x")
    code, _, err = run_cli("run", tiny, "--out", out)
    assert code == EXIT_ERROR and "is a file, not a folder" in err


def test_out_under_a_file_is_refused_before_the_work(tiny, tmp_path, run_cli, monkeypatch):
    (tmp_path / "file").write_text("x")
    monkeypatch.setattr("lost.host.scenario.simulate", _must_not_run)
    code, _, err = run_cli("run", tiny, "--out", tmp_path / "file" / "run")
    assert code == EXIT_ERROR and "is not a folder" in err


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_an_unwritable_parent_is_refused_before_the_work(tiny, tmp_path, run_cli, monkeypatch):
    locked = tmp_path / "ro"
    locked.mkdir()
    locked.chmod(0o555)
    monkeypatch.setattr("lost.host.scenario.simulate", _must_not_run)
    code, _, err = run_cli("run", tiny, "--out", locked / "run")
    locked.chmod(0o755)
    assert code == EXIT_ERROR and "not writable" in err


def test_an_unwritable_parent_is_refused_before_the_work_even_as_root(tiny, tmp_path, run_cli, monkeypatch):
    monkeypatch.setattr(runfolder.os, "access", lambda *a: False)
    monkeypatch.setattr("lost.host.scenario.simulate", _must_not_run)
    code, _, err = run_cli("run", tiny, "--out", tmp_path / "run")
    assert code == EXIT_ERROR and "is not writable" in err


def test_a_nearly_full_disk_is_refused_before_the_work(tiny, tmp_path, run_cli, monkeypatch):
    full = runfolder.shutil.disk_usage(tmp_path)._replace(free=1024)
    monkeypatch.setattr(runfolder.shutil, "disk_usage", lambda path: full)
    monkeypatch.setattr("lost.host.scenario.simulate", _must_not_run)
    code, _, err = run_cli("run", tiny, "--out", tmp_path / "run")
    assert code == EXIT_ERROR and "1 kB free" in err


def test_ctrl_c_leaves_the_previous_run_intact_and_says_so(tiny, tmp_path, run_cli, monkeypatch):
    out = tmp_path / "a"
    assert run_cli("run", tiny, "--out", out)[0] == EXIT_OK
    before = {name: (out / name).read_bytes() for name in _files(out)}

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr("lost.host.plotting.draw_plots", interrupted)  # after track.csv is written
    code, _, err = run_cli("run", tiny, "--out", out, "--replace")
    assert code == EXIT_INTERRUPTED and "interrupted; the previous run in" in err and "is intact" in err
    assert {name: (out / name).read_bytes() for name in _files(out)} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "tiny.toml"]


def test_ctrl_c_on_a_first_run_leaves_nothing(tiny, tmp_path, run_cli, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr("lost.host.cli.run.write_summary", interrupted)
    code, _, err = run_cli("run", tiny, "--out", tmp_path / "a")
    assert code == EXIT_INTERRUPTED and "nothing was written to" in err
    assert not (tmp_path / "a").exists()


def test_a_failed_write_leaves_no_half_written_track(tiny, tmp_path, run_cli, monkeypatch):
    out = tmp_path / "a"
    assert run_cli("run", tiny, "--out", out)[0] == EXIT_OK
    summary = (out / "summary.json").read_text()

    def disk_full(path, *args, **kwargs):
        path.write_text("t_s,est_x_m\n0.0,")  # half a file, then the disk fills
        raise OSError(28, "No space left on device", str(path))

    monkeypatch.setattr("lost.host.report.write_track_csv", disk_full)
    code, _, err = run_cli("run", tiny, "--out", out, "--replace")
    assert code == EXIT_ERROR and "No space left on device" in err and "is intact" in err
    assert (out / "summary.json").read_text() == summary and (out / "track.csv").read_text().count("\n") > 10


def test_a_second_run_on_a_locked_folder_is_refused(tiny, tmp_path, run_cli):
    out = tmp_path / "a"
    with run_folder(out) as folder:
        code, _, err = run_cli("run", tiny, "--out", out)
        assert code == EXIT_ERROR and f"(pid {os.getpid()}) is writing to" in err
        (folder / "summary.json").write_text("{}")
    assert _files(out) == ["lost-run.json", "summary.json"]


def test_the_lock_is_released_after_a_failed_run(tmp_path):
    out = tmp_path / "a"
    with pytest.raises(RuntimeError), run_folder(out):
        raise RuntimeError("boom")
    with run_folder(out) as folder:
        (folder / "summary.json").write_text("{}")
    assert (out / "summary.json").read_text() == "{}"


def test_debug_shows_the_traceback_of_a_failed_run(tiny, tmp_path, capsys):
    from lost.host.cli import main

    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "x").write_text("x")
    assert main(["run", str(tiny), "--out", str(tmp_path / "a"), "--debug"]) == EXIT_ERROR
    err = capsys.readouterr().err
    assert "Traceback" in err and "RunFolderError" in err and err.strip().splitlines()[-1].startswith("lost run: ")


def test_an_unexpected_error_is_one_line_that_asks_for_debug(tiny, tmp_path, run_cli, monkeypatch):
    def bug(*args, **kwargs):
        raise ZeroDivisionError("division by zero")

    monkeypatch.setattr("lost.host.report.summarize", bug)
    code, _, err = run_cli("run", tiny, "--out", tmp_path / "a")
    assert code == EXIT_ERROR and "internal error (ZeroDivisionError" in err and "--debug" in err
    assert not (tmp_path / "a").exists()


def test_the_demo_replaces_its_own_folder(tmp_path, run_cli, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "runs" / "demo").mkdir(parents=True)
    (tmp_path / "runs" / "demo" / "lost-run.json").write_text('{"lost_run": 1, "command": "demo"}')
    monkeypatch.setattr("lost.host.scenario.builtin_scenario_path", lambda name: tmp_path / "tiny.toml")
    from .conftest import TINY_SCENARIO

    (tmp_path / "tiny.toml").write_text(TINY_SCENARIO)
    assert run_cli("demo")[0] == EXIT_OK
    assert json.loads((tmp_path / "runs" / "demo" / "summary.json").read_text())["name"] == "tiny"


def _must_not_run(*args, **kwargs):
    raise AssertionError("the work started before the output folder was checked")


def test_sigterm_unwinds_like_ctrl_c(tiny, tmp_path, run_cli, monkeypatch):
    import signal

    def terminated(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr("lost.host.plotting.draw_plots", terminated)
    code, _, err = run_cli("run", tiny, "--out", tmp_path / "a")
    assert code == EXIT_INTERRUPTED and "interrupted; nothing was written to" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tiny.toml"]
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL


def test_a_killed_runs_leftovers_are_cleared_by_the_next_run(tiny, tmp_path, run_cli):
    (tmp_path / ".a.partial-dead").mkdir()
    (tmp_path / ".a.partial-dead" / "track.csv").write_text("t_s\n0,")
    assert run_cli("run", tiny, "--out", tmp_path / "a")[0] == EXIT_OK
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "tiny.toml"]


def test_a_run_set_aside_by_a_replacement_that_died_is_put_back(tiny, tmp_path, run_cli):
    aside = tmp_path / ".a.old-dead" / "run"
    aside.mkdir(parents=True)
    (aside / "summary.json").write_text('{"name": "the previous run"}')
    (aside / "lost-run.json").write_text('{"lost_run": 1, "command": "run"}')
    code, _, err = run_cli("run", tiny, "--out", tmp_path / "a")
    assert code == EXIT_ERROR and "already holds a run" in err  # it is back, and not overwritten without --replace
    assert json.loads((tmp_path / "a" / "summary.json").read_text())["name"] == "the previous run"


def test_a_folder_name_with_glob_characters_is_no_pattern(tiny, tmp_path, run_cli):
    (tmp_path / ".run1.partial-other").mkdir()  # another folder's leftovers, which run[1]'s pattern would match
    assert run_cli("run", tiny, "--out", tmp_path / "run[1]")[0] == EXIT_OK
    assert (tmp_path / ".run1.partial-other").is_dir() and (tmp_path / "run[1]" / "summary.json").is_file()
