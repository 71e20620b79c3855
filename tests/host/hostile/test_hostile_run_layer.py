"""The run layer under hostile use: every subcommand writes through the atomic run folder, a folder must be a LOST run
to be replaced, a failing plot is a warning and never costs the summary, and a map's plot uses its canvas."""

from __future__ import annotations

import json
import os

import pytest

from lost.host.cli import EXIT_ERROR, EXIT_OK
from lost.host.plotting import draw_plots, map_figure_size
from lost.host.runfolder import RUN_MARKER, RunFolderError, holds_a_run, run_folder


def _track(run_cli, scenario, out, *extra):
    return run_cli("track", scenario, "--out", out, "--particles", "500", "--no-animation", *extra)


def test_replace_refuses_a_folder_holding_another_tools_summary(tiny, tmp_path, run_cli):
    out = tmp_path / "theirs"
    out.mkdir()
    (out / "summary.json").write_text('{"tool": "someone else"}')
    (out / "notes.txt").write_text("the user's own notes")
    code, _, err = run_cli("run", tiny, "--out", out, "--replace")
    assert code == EXIT_ERROR and "holds no LOST run" in err and RUN_MARKER in err
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt", "summary.json"]


def test_a_symbolic_link_as_out_is_refused_and_left_alone(tiny, tmp_path, run_cli):
    target = tmp_path / "target"
    target.mkdir()
    link = tmp_path / "link"
    link.symlink_to(target)
    code, _, err = run_cli("run", tiny, "--out", link)
    assert code == EXIT_ERROR and "is a symbolic link" in err
    assert link.is_symlink() and list(target.iterdir()) == []


def test_track_does_not_mix_its_files_into_a_navigation_run(tiny, tiny_track, tmp_path, run_cli):
    out = tmp_path / "run"
    assert run_cli("run", tiny, "--out", out)[0] == EXIT_OK
    navigation = {p.name: p.read_bytes() for p in out.iterdir()}
    code, _, err = _track(run_cli, tiny_track, out)
    assert code == EXIT_ERROR and "already holds a run" in err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == navigation
    assert _track(run_cli, tiny_track, out, "--replace")[0] == EXIT_OK
    names = {p.name for p in out.iterdir()}
    assert {"tracks.csv", "sector.png", "summary.json", RUN_MARKER} == names  # replaced whole: no track.csv or map.png left
    assert json.loads((out / RUN_MARKER).read_text())["command"] == "track"


def test_track_and_usbl_name_a_file_given_as_out(tiny_track, tmp_path, run_cli):
    afile = tmp_path / "a.txt"
    afile.write_text("mine")
    code, _, err = _track(run_cli, tiny_track, afile)
    assert code == EXIT_ERROR and f"--out {afile} is a file, not a folder" in err
    code, _, err = run_cli("usbl", "usbl_turns", "--out", afile)
    assert code == EXIT_ERROR and f"--out {afile} is a file, not a folder" in err
    assert afile.read_text() == "mine"


def test_a_second_track_run_on_a_locked_folder_is_refused(tiny_track, tmp_path, run_cli):
    out = tmp_path / "t"
    with run_folder(out, command="track"):
        code, _, err = _track(run_cli, tiny_track, out)
    assert code == EXIT_ERROR and f"(pid {os.getpid()}) is writing to" in err


def test_a_failing_plot_is_a_warning_and_the_run_is_kept(tiny_track, tmp_path, run_cli, monkeypatch):
    def broken(*args, **kwargs):
        raise ValueError("the ray turns before the vehicle")

    monkeypatch.setattr("lost.host.track.plots.plot_sector", broken)
    out = tmp_path / "t"
    code, stdout, _ = _track(run_cli, tiny_track, out)
    assert code == EXIT_OK
    summary = json.loads((out / "summary.json").read_text())
    assert summary["warnings"] == ["sector.png was not drawn: ValueError: the ray turns before the vehicle"]
    assert (out / "tracks.csv").stat().st_size > 0 and not (out / "sector.png").exists()
    assert "sector.png" not in stdout


def test_draw_plots_keeps_going_after_a_failure(tmp_path):
    warnings: list[str] = []

    def good(path):
        path.write_bytes(b"png")

    def bad(path):
        path.write_bytes(b"half")
        raise RuntimeError("no font")

    written = draw_plots(tmp_path, {"a.png": bad, "b.png": good}, warnings)
    assert written == [tmp_path / "b.png"] and not (tmp_path / "a.png").exists()
    assert warnings == ["a.png was not drawn: RuntimeError: no font"]


def test_a_run_that_cannot_be_moved_aside_leaves_no_stray_folder(tmp_path, monkeypatch):
    out = tmp_path / "a"
    with run_folder(out) as folder:
        (folder / "summary.json").write_text("{}")
    real_replace = os.replace

    def refuse(src, dst):
        if os.fspath(src) == os.fspath(out):
            raise PermissionError(13, "Permission denied")
        return real_replace(src, dst)

    monkeypatch.setattr("lost.host.runfolder.os.replace", refuse)
    with pytest.raises(RunFolderError, match="cannot replace the run in .*Permission denied"), run_folder(out, replace=True) as folder:
        (folder / "summary.json").write_text('{"new": 1}')
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a"] and holds_a_run(out)
    assert (out / "summary.json").read_text() == "{}"


def test_the_marker_must_read_as_ours(tmp_path):
    (tmp_path / RUN_MARKER).write_text("not json")
    assert not holds_a_run(tmp_path)
    (tmp_path / RUN_MARKER).write_text('{"lost_run": 1}')
    assert holds_a_run(tmp_path)


@pytest.mark.parametrize(("width_m", "height_m"), [(4000.0, 2000.0), (1000.0, 2500.0), (2000.0, 2000.0)])
def test_a_map_gets_the_canvas_along_its_longer_side(width_m, height_m):
    width_in, height_in = map_figure_size(width_m, height_m)
    map_w, map_h = width_in - 1.8, height_in - 1.0
    assert max(map_w, map_h) == pytest.approx(10.0)
    assert map_h / map_w == pytest.approx(height_m / width_m)


def test_a_failing_run_keeps_what_it_wrote_as_it_went(tmp_path):
    out = tmp_path / "serve"
    with pytest.warns(UserWarning, match=r"stopped run's log.jsonl kept in .*serve\.stopped-"), pytest.raises(RuntimeError, match="disk"):
        with run_folder(out, command="serve", keep=("log.jsonl",)) as folder:
            (folder / "log.jsonl").write_text('{"record": 0}\n{"record": 1}\n')
            raise RuntimeError("the disk is full")
    assert not out.exists()
    (stopped,) = tmp_path.glob("serve.stopped-*")
    assert (stopped / "log.jsonl").read_text().count("record") == 2


def test_a_killed_run_s_log_is_set_aside_not_deleted_by_the_next_run(tmp_path):
    out = tmp_path / "serve"
    killed = tmp_path / ".serve.partial-dead1"  # what a SIGKILLed lost serve leaves
    killed.mkdir()
    (killed / ".lost-keep").write_text("log.jsonl\n")
    (killed / "log.jsonl").write_text('{"record": 0}\n')
    dead_plot = tmp_path / ".serve.partial-dead2"  # a killed batch run: nothing to keep
    dead_plot.mkdir()
    (dead_plot / "track.csv").write_text("t\n")
    with pytest.warns(UserWarning, match=r"killed run's log.jsonl kept in .*serve\.stopped-"):
        with run_folder(out, command="serve", keep=("log.jsonl",)) as folder:
            (folder / "log.jsonl").write_text('{"record": 0}\n')
    (stopped,) = tmp_path.glob("serve.stopped-*")
    assert (stopped / "log.jsonl").read_text() == '{"record": 0}\n'
    assert not killed.exists() and not dead_plot.exists()
    assert sorted(p.name for p in out.iterdir()) == ["log.jsonl", RUN_MARKER]  # the finished run keeps no keep-marker
