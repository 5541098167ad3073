"""Safe writes (issue 30, item 5): outputs.write_text_atomic never follows a symlink planted beside
the output, never replaces a device node, FIFO or symlink with a regular file, refuses a folder or an
unwritable folder in one line without leaving a temporary, and '-' is stdout on the CLI."""

import os
import stat
from pathlib import Path

import pytest

from qmt_drake.apps.cli import main
from qmt_drake.errors import QmtInputError
from qmt_drake.outputs import atomic_output, check_one_stdout, check_output_path, write_text_atomic


def _one_line(exc) -> str:
    msg = str(exc.value)
    assert "\n" not in msg
    return msg


def test_symlink_planted_at_the_old_temporary_name_is_not_followed(tmp_path):
    """The old writer's temporary was `.NAME.PID.tmp`; a symlink planted there overwrote its target."""
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    out = tmp_path / "out.json"
    (tmp_path / f".out.json.{os.getpid()}.tmp").symlink_to(victim)
    write_text_atomic(out, "{}\n")
    assert victim.read_text() == "precious\n"
    assert out.read_text() == "{}\n" and not out.is_symlink()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([f".out.json.{os.getpid()}.tmp", "out.json",
                                                                 "victim.txt"])


def test_new_file_gets_the_umask_mode_not_mkstemps_0600(tmp_path):
    out = tmp_path / "a.json"
    write_text_atomic(out, "1\n")
    mask = os.umask(0)
    os.umask(mask)
    assert stat.S_IMODE(out.stat().st_mode) == 0o666 & ~mask


def test_symlink_output_stays_a_link_and_its_target_gets_the_text(tmp_path):
    target = tmp_path / "real.json"
    target.write_text("old\n")
    link = tmp_path / "link.json"
    link.symlink_to(target)
    write_text_atomic(link, "new\n")
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert target.read_text() == "new\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.json", "real.json"]


def test_dev_null_is_written_through_not_replaced(tmp_path, monkeypatch):
    def no_replace(*a):  # a regression must fail here, not replace /dev/null (the tests may run as root)
        raise AssertionError("os.replace called for a device node")
    monkeypatch.setattr(os, "replace", no_replace)
    check_output_path("/dev/null", "--json")
    write_text_atomic("/dev/null", "discarded\n")
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
    link = tmp_path / "null"
    link.symlink_to("/dev/null")
    write_text_atomic(link, "discarded\n")
    assert link.is_symlink() and stat.S_ISCHR(os.stat("/dev/null").st_mode)


def test_link_to_own_descriptor_writes_through_it(tmp_path):
    """/dev/stdout -> /proc/self/fd/1 with stdout redirected to a file (`>` or `>>`): the text goes
    through that descriptor, between what was written before and after, and the file is not replaced."""
    for mode in ("w", "a"):
        log = tmp_path / f"log_{mode}.txt"
        with open(log, mode) as fh:
            fh.write("first\n")
            fh.flush()
            for link in (tmp_path / f"stdout_{mode}", f"/dev/fd/{fh.fileno()}"):
                if isinstance(link, Path):
                    link.symlink_to(f"/proc/self/fd/{fh.fileno()}")
                write_text_atomic(link, "second\n")
            fh.write("third\n")
        assert log.read_text() == "first\nsecond\nsecond\nthird\n"
        assert (tmp_path / f"stdout_{mode}").is_symlink()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log_a.txt", "log_w.txt", "stdout_a", "stdout_w"]


def test_fifo_is_written_through_and_one_without_reader_is_one_line(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    with pytest.raises(QmtInputError) as exc:  # nobody reads: refused at once, not a hang
        write_text_atomic(fifo, "lost\n")
    assert "is a FIFO that nobody reads" in _one_line(exc)
    reader = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)  # the reader's end, open before the write
    try:
        write_text_atomic(fifo, "through the pipe\n")
        assert os.read(reader, 1000) == b"through the pipe\n"
    finally:
        os.close(reader)
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    assert [p.name for p in tmp_path.iterdir()] == ["pipe"]


def test_directory_output_is_one_line_and_leaves_no_temporary(tmp_path):
    d = tmp_path / "results"
    d.mkdir()
    with pytest.raises(QmtInputError) as exc:
        write_text_atomic(d, "x")
    assert f"{d} is a directory; give a file name inside it" in _one_line(exc)
    with pytest.raises(QmtInputError, match="is a directory"):
        check_output_path(d, "--json")
    assert [p.name for p in tmp_path.iterdir()] == ["results"] and not any(d.iterdir())


def test_unwritable_folder_and_dangling_link_are_one_line(tmp_path):
    with pytest.raises(QmtInputError) as exc:  # /proc refuses new files even to root
        write_text_atomic("/proc/qmt_drake_out.json", "x")
    assert "folder /proc is not writable" in _one_line(exc)
    dangling = tmp_path / "dangling.json"
    dangling.symlink_to(tmp_path / "missing" / "x.json")
    with pytest.raises(QmtInputError) as exc:
        write_text_atomic(dangling, "x")
    assert "is a symlink to" in _one_line(exc) and "remove the link" in str(exc.value)
    assert not (tmp_path / "missing").exists()


def test_failure_while_writing_removes_the_temporary_and_keeps_the_old_file(tmp_path):
    out = tmp_path / "fig.png"
    out.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_output(out, suffix=".tmp.png") as tmp:
            assert tmp.parent == tmp_path and tmp.name.endswith(".tmp.png") and tmp.exists()
            tmp.write_text("half")
            raise RuntimeError("the writer crashed")
    assert out.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["fig.png"]


def test_dash_is_stdout_and_refused_where_stdout_makes_no_sense(capsys):
    write_text_atomic("-", "to stdout\n")
    assert capsys.readouterr().out == "to stdout\n"
    for flag in ("--record", "--recording", "--checkpoint"):
        with pytest.raises(QmtInputError) as exc:
            check_output_path("-", flag)
        assert _one_line(exc).startswith(f"{flag} -: this output is not written to stdout")
    with pytest.raises(QmtInputError) as exc:
        check_one_stdout({"--json": "-", "--trajectory-csv": "-"})
    assert "--json and --trajectory-csv all write to stdout" in _one_line(exc)


def test_cli_trajectory_csv_dash_goes_to_stdout(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    rc = main(["plan", "thesis-ch2", "--method", "thesis", "--trajectory-csv", "-", "--quiet"])
    out, _ = capsys.readouterr()
    assert rc == 0 and not (tmp_path / "-").exists()
    lines = out.splitlines()
    assert lines[0] == "t,q1,q2,q3,qd1,qd2,qd3,qdd1,qdd2,qdd3" and len(lines) > 1000  # 1 kHz, no summary line
    assert all(len(r.split(",")) == 10 for r in lines[1:])


def test_cli_record_dash_and_two_stdouts_are_refused_before_work(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "thesis-ch4", "--method", "thesis", "--record", "-"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--record -: this output is not written to stdout" in err and len(err.splitlines()) == 1
    assert main(["plan", "thesis-ch2", "--method", "thesis", "--json", "-", "--trajectory-csv", "-"]) == 2
    err = capsys.readouterr().err.strip()
    assert "all write to stdout" in err and len(err.splitlines()) == 1
    assert list(tmp_path.iterdir()) == []
