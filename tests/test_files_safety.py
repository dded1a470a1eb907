"""The output folder guards the user's files: the manifest records every file
tmtcontrol wrote (path, size, SHA-256), anything else in a previous output
makes it foreign (refused, one line, nothing touched), the target is checked
again at commit, a full disk is one line, a killed run's litter is cleaned,
concurrent commits are serialised, and summary.json is strict JSON.

Most cases drive :class:`tmtcontrol.files.OutputFolder` directly with small
fake outputs (fast); a few go through the CLI to check the exit code and the
one line."""
import errno
import hashlib
import json
import math
import os
import pathlib
import subprocess
import sys

import pytest

from tmtcontrol.cli import main
from tmtcontrol.files import (MANIFEST, MANIFEST_FORMAT, NOT_SAVED_EXIT, OutputError, OutputFolder, OutputNotSaved,
                              write_json)

CLI = [sys.executable, "-m", "tmtcontrol.cli"]
SHORT = ["--set", "trajectory.cycles=0.1", "--no-plots"]
FILES = {"summary.json": b'{"a": 1}\n', "sub/timeseries.csv": b"t,f\n0,1\n", "sub/deeper/x.bin": bytes(range(256))}


def commit(out, files=FILES, flag="--out"):
    """A fake tmtcontrol output: ``files`` (relative path -> bytes) committed to ``out``."""
    with OutputFolder(out, flag) as folder:
        for rel, data in files.items():
            (folder.path / rel).parent.mkdir(parents=True, exist_ok=True)
            (folder.path / rel).write_bytes(data)
        folder.commit("test")
    return out


def snapshot(folder):
    """Everything below ``folder`` (links not followed): path -> content, link target or 'dir'."""
    out = {}
    for root, dirs, files in os.walk(folder):
        for name in dirs + files:
            p = pathlib.Path(root) / name
            rel = str(p.relative_to(folder))
            out[rel] = (("link", os.readlink(p)) if p.is_symlink() else "dir" if p.is_dir()
                        else p.read_bytes() if p.is_file() else "other")
    return out


def litter(parent):
    return sorted(p.name for p in parent.iterdir() if ".tmt-" in p.name)


# -- item 1: the manifest covers every file, with its content hash ---------------------

def test_manifest_lists_every_file_in_every_subfolder_with_its_sha256(tmp_path):
    out = commit(tmp_path / "o", {**FILES, ".hidden": b"h"})
    m = json.loads((out / MANIFEST).read_text())
    assert m["written_by"] == "tmtcontrol" and m["format"] == MANIFEST_FORMAT and m["command"] == "test"
    assert m["folders"] == ["sub", "sub/deeper"]
    expected = {rel: {"size": len(data), "sha256": hashlib.sha256(data).hexdigest()}    # hashlib: the reference
                for rel, data in {**FILES, ".hidden": b"h"}.items()}
    assert m["files"] == expected


def test_a_previous_output_is_replaced_whole(tmp_path):
    out = commit(tmp_path / "o")
    commit(out, {"new.txt": b"n"})
    assert snapshot(out) == {"new.txt": b"n", MANIFEST: (out / MANIFEST).read_bytes()}
    assert litter(tmp_path) == []


def _add_user_file(out):
    (out / "sub" / "my_analysis.txt").write_text("notes")


def _edit_same_size(out):                       # same length: a size check alone does not see it
    (out / "summary.json").write_bytes(b'{"a": 2}\n')


def _edit_longer(out):
    (out / "summary.json").write_bytes(b'{"a": 1, "mine": true}\n')


def _hidden_file(out):
    (out / ".notes").write_text("mine")


def _hidden_git(out):
    (out / ".git").mkdir()
    (out / ".git" / "HEAD").write_text("ref: refs/heads/main\n")


def _empty_folder(out):
    (out / "sub" / "mine").mkdir()


def _symlink_substituted(out, tmp_path=None):
    target = out.parent / "elsewhere.csv"
    target.write_bytes(FILES["sub/timeseries.csv"])            # the same content, through a link
    (out / "sub" / "timeseries.csv").unlink()
    (out / "sub" / "timeseries.csv").symlink_to(target)


def _fifo(out):
    os.mkfifo(out / "sub" / "pipe")


def _old_manifest(out):                          # version 1: names only, no format, no hashes
    (out / MANIFEST).write_text(json.dumps({"written_by": "tmtcontrol", "version": "0.0.9",
                                            "files": ["summary.json", "sub"]}))


def _damaged_manifest(out):
    m = json.loads((out / MANIFEST).read_text())
    m["files"]["summary.json"]["sha256"] = "not a hash"
    (out / MANIFEST).write_text(json.dumps(m))


@pytest.mark.parametrize("change,reason", [
    (_add_user_file, "o/sub/my_analysis.txt is not a file tmtcontrol wrote"),
    (_edit_same_size, "o/summary.json was changed after tmtcontrol wrote it"),
    (_edit_longer, "o/summary.json was changed after tmtcontrol wrote it"),
    (_hidden_file, "o/.notes is not a file tmtcontrol wrote"),
    (_hidden_git, "o/.git/ is a folder tmtcontrol did not write"),
    (_empty_folder, "o/sub/mine/ is a folder tmtcontrol did not write"),
    (_symlink_substituted, "o/sub/timeseries.csv is a symbolic link tmtcontrol did not write"),
    (_fifo, "o/sub/pipe is not a file tmtcontrol wrote"),
    (_old_manifest, "o was written by an older tmtcontrol"),
    (_damaged_manifest, "o holds a damaged tmtcontrol manifest"),
])
def test_anything_not_written_by_tmtcontrol_makes_the_folder_foreign(tmp_path, monkeypatch, change, reason):
    monkeypatch.chdir(tmp_path)
    out = commit(pathlib.Path("o"))
    change(out)
    before = snapshot(tmp_path)
    with pytest.raises(OutputError) as err:
        OutputFolder("o", "--plot")
    msg = str(err.value)
    assert msg.startswith("--plot: ") and reason in msg and "\n" not in msg, msg
    assert snapshot(tmp_path) == before and litter(tmp_path) == []


def test_a_foreign_json_manifest_does_not_make_a_folder_replaceable(tmp_path):
    """A manifest of the right name and shape, with correct hashes, but not
    tmtcontrol's signature (another tool's, or hand-written) is foreign."""
    out = tmp_path / "data"
    out.mkdir()
    (out / "measurements.csv").write_bytes(b"1,2\n")
    entry = {"size": 4, "sha256": hashlib.sha256(b"1,2\n").hexdigest()}
    for manifest in ({"files": {"measurements.csv": entry}, "folders": []},
                     {"written_by": "othertool", "format": MANIFEST_FORMAT,
                      "files": {"measurements.csv": entry}, "folders": []},
                     {"written_by": "tmtcontrol", "format": "othertool/2",
                      "files": {"measurements.csv": entry}, "folders": []},
                     ["measurements.csv"]):
        (out / MANIFEST).write_text(json.dumps(manifest))
        before = snapshot(out)
        with pytest.raises(OutputError, match="did not write|older tmtcontrol"):
            OutputFolder(out)
        assert snapshot(out) == before
    # the same folder with tmtcontrol's signature is a previous output: replaced
    (out / MANIFEST).write_text(json.dumps({"written_by": "tmtcontrol", "format": MANIFEST_FORMAT,
                                            "files": {"measurements.csv": entry}, "folders": []}))
    commit(out, {"a": b"a"})
    assert not (out / "measurements.csv").exists()


def test_a_symlink_to_a_folder_is_never_replaced(tmp_path):
    """--out LINK where LINK points at a previous tmtcontrol output (replaceable
    in itself): the link is refused, the link and its target left as they were."""
    real = commit(tmp_path / "real")
    link = tmp_path / "link"
    link.symlink_to(real, target_is_directory=True)
    before = snapshot(tmp_path)
    with pytest.raises(OutputError, match=r"^--out: .*link is a symbolic link"):
        OutputFolder(link)
    assert snapshot(tmp_path) == before and link.is_symlink()


def test_a_file_saved_into_the_target_during_the_run_is_not_deleted(tmp_path):
    """Checked again at commit: the run's results are not saved (OutputNotSaved,
    not bad input), the user's file and the previous output stay."""
    out = commit(tmp_path / "o")
    with pytest.raises(OutputNotSaved, match=r"^--out: \S+ changed during the run: .*notes.txt is not a file "
                                             "tmtcontrol wrote; the results were not saved"):
        with OutputFolder(out) as folder:
            (folder.path / "new.txt").write_text("result")
            (out / "notes.txt").write_text("saved by the user while the run computed")
            folder.commit()
    assert (out / "notes.txt").read_text() == "saved by the user while the run computed"
    assert (out / "summary.json").read_bytes() == FILES["summary.json"] and not (out / "new.txt").exists()
    assert litter(tmp_path) == []


def test_cli_refuses_a_user_file_in_a_subfolder_of_a_previous_compare(tmp_path):
    """Issue 27's reproduction: compare, save notes into cmp/tmt/, compare again."""
    args = ["compare", "--laws", "tmt,known", "--out", "cmp", *SHORT]
    first = subprocess.run(CLI + args, capture_output=True, text=True, cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    (tmp_path / "cmp" / "tmt" / "my_analysis.txt").write_text("notes")
    before = snapshot(tmp_path)
    r = subprocess.run(CLI + args, capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr == ("error: --out: cmp/tmt/my_analysis.txt is not a file tmtcontrol wrote; "
                        "choose another folder or move it (nothing was written)\n")
    assert snapshot(tmp_path) == before


def test_cli_reports_a_target_changed_during_the_run_as_not_saved(tmp_path, monkeypatch, capsys):
    """Exit 3 (results not saved), one line: a race is not the user's bad input."""
    import tmtcontrol.simulation.output as output

    out = commit(tmp_path / "o")
    original = output.save_simulation

    def save_then_user_writes(res, folder, **kw):
        original(res, folder, **kw)
        (out / "sub" / "mine.txt").write_text("mine")

    monkeypatch.setattr(output, "save_simulation", save_then_user_writes)
    assert main(["simulate", *SHORT, "--out", str(out)]) == NOT_SAVED_EXIT == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "changed during the run" in err[0] and "mine.txt" in err[0], err
    assert (out / "sub" / "mine.txt").read_text() == "mine" and litter(tmp_path) == []


# -- item 7: modes and strict JSON ------------------------------------------------------

@pytest.mark.parametrize("umask", [0o022, 0o027])
def test_results_get_the_modes_of_any_file_the_user_writes(tmp_path, umask):
    """Not the 0700 of a private temporary folder: folders 0777 & ~umask,
    files 0666 & ~umask, as ``mkdir`` and ``open`` would give."""
    old = os.umask(umask)
    try:
        out = commit(tmp_path / "o")
    finally:
        os.umask(old)
    assert (out.stat().st_mode & 0o777) == 0o777 & ~umask
    assert ((out / "sub").stat().st_mode & 0o777) == 0o777 & ~umask
    for rel in (*FILES, MANIFEST):
        assert ((out / rel).stat().st_mode & 0o777) == 0o666 & ~umask, rel


def _no_constants(name):
    raise ValueError(f"invalid JSON constant {name}")


def test_write_json_writes_non_finite_numbers_as_null(tmp_path):
    import numpy as np

    obj = {"nan": float("nan"), "inf": math.inf, "list": [-math.inf, 1.5, np.float32("nan")],
           "array": np.array([1.0, np.nan, np.inf]), "np": np.float64(-np.inf), "ok": np.int64(3),
           "nested": {"t": (np.nan, 2)}}
    write_json(tmp_path / "s.json", obj)
    back = json.loads((tmp_path / "s.json").read_text(), parse_constant=_no_constants)   # strict JSON
    assert back == {"nan": None, "inf": None, "list": [None, 1.5, None], "array": [1.0, None, None], "np": None,
                    "ok": 3, "nested": {"t": [None, 2]}}


def test_write_json_refuses_rather_than_writes_invalid_json(tmp_path, monkeypatch):
    """Should a non-finite number reach the encoder (a converter that misses a
    type), the write fails; ``NaN``/``Infinity`` tokens are never written."""
    import tmtcontrol.files as files

    monkeypatch.setattr(files, "jsonable", lambda obj: obj)
    with pytest.raises(ValueError, match="not JSON compliant"):
        write_json(tmp_path / "s.json", {"x": float("nan")})
    assert not (tmp_path / "s.json").exists() or "NaN" not in (tmp_path / "s.json").read_text()


def test_simulate_summary_is_strict_json(tmp_path):
    """A run whose stiffness estimate is NaN before contact: summary.json still parses strictly."""
    assert main(["simulate", *SHORT, "--out", str(tmp_path / "o")]) == 0
    json.loads((tmp_path / "o" / "summary.json").read_text(), parse_constant=_no_constants)


# -- item 2: a full disk is one line; nothing partial is left -------------------------------

def _enospc(filename=None):
    return OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), filename)


def test_full_disk_during_simulate_is_one_line_and_keeps_the_previous_output(tmp_path, monkeypatch, capsys):
    """Injected: the CSV writer meets ENOSPC half-way. Exit 3, one line naming
    the folder and the need for space, the staging folder removed, the
    previous output as it was."""
    import tmtcontrol.simulation.output as output

    out = commit(tmp_path / "o")
    before = snapshot(tmp_path)

    def full(res, path, **kw):
        pathlib.Path(path).write_bytes(b"time,contact_force\n0,0\n")    # part of it, then the disk is full
        raise _enospc(str(path))

    monkeypatch.setattr(output, "write_timeseries", full)
    assert main(["simulate", *SHORT, "--out", str(out)]) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: --out: no space left on the disk holding {out} ("), err
    assert "free some space" in err[0]
    assert snapshot(tmp_path) == before and litter(tmp_path) == []


def test_full_disk_reported_only_as_text_by_a_worker_process_is_recognised(tmp_path):
    """A figure or report worker hands back only the traceback's text."""
    with pytest.raises(OutputNotSaved, match="no space left on the disk holding"):
        with OutputFolder(tmp_path / "o"):
            raise RuntimeError("drawing the figures failed:\nOSError: [Errno 28] No space left on device: 'x.png'")
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(RuntimeError, match="^other$"):            # any other error passes through unchanged
        with OutputFolder(tmp_path / "o"):
            raise RuntimeError("other")
    assert list(tmp_path.iterdir()) == []


@pytest.fixture
def small_disk(tmp_path):
    """A 2 MiB tmpfs (root may mount one here; skipped where mounting is refused,
    the injected tests above always run)."""
    disk = tmp_path / "disk"
    disk.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(disk)], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {r.stderr.strip()}")
    try:
        yield disk
    finally:
        subprocess.run(["umount", "-l", str(disk)], check=False)


def _fill(disk, leave):
    """Fill ``disk`` up to ``leave`` free bytes with a user's file."""
    st = os.statvfs(disk)
    free = st.f_bavail * st.f_frsize
    with open(disk / "filler.bin", "wb") as fh:
        fh.write(b"\0" * max(free - leave, 0))


def test_full_tmpfs_during_simulate(small_disk):
    out = small_disk / "o"
    args = CLI + ["simulate", *SHORT, "--out", str(out)]
    assert subprocess.run(args, capture_output=True, text=True).returncode == 0
    _fill(small_disk, leave=40_000)                # the CSV of this run takes about 105 kB
    before = snapshot(small_disk)
    r = subprocess.run(args, capture_output=True, text=True)
    assert r.returncode == 3, r.stderr
    assert r.stderr.startswith(f"error: --out: no space left on the disk holding {out} (No space left on device)")
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr
    assert snapshot(small_disk) == before and litter(small_disk) == []


def toy_step(scale=1.0):
    import casadi as ca

    s, u, p = ca.SX.sym("s", 2), ca.SX.sym("u", 1), ca.SX.sym("p", 1)
    return ca.Function("fulltoy", [s, u, p], [ca.vertcat(s[0] + scale * u, s[1] * p), ca.vertcat(s, u)],
                       ["s", "u", "p"], ["s_next", "log"])


def _check_runs(r, scale=1.0):
    import numpy as np

    U = np.arange(30, dtype=float)[None, :]
    S, _ = r.run([0.0, 1.0], U, [2.0])
    np.testing.assert_array_equal(S[0], np.cumsum(scale * U))    # exact: sums of small integers
    np.testing.assert_array_equal(S[1], 2.0 ** np.arange(1, 31))  # exact: powers of two


@pytest.fixture
def private_tmp(tmp_path, monkeypatch):
    """tempfile's folder (build folders, the per-user fallback) inside this test's tmp_path."""
    import tempfile

    t = tmp_path / "tmp"
    t.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(t))
    return t


def _full_open(real_open=open):
    def fake(path, mode="r", *a, **kw):
        fh = real_open(path, mode, *a, **kw)
        if "w" not in mode:
            return fh

        class Full:
            def __enter__(self):
                return self

            def __exit__(self, *exc):
                fh.close()

            def write(self, data):
                fh.write(data[:len(data) // 2])                     # half of it, then the disk is full
                raise _enospc(str(path))

            def __getattr__(self, name):
                return getattr(fh, name)

        return Full()
    return fake


def test_full_disk_while_caching_a_library_leaves_nothing_partial(tmp_path, private_tmp, monkeypatch):
    """Injected ENOSPC while the library is staged: the staged .so.PID.tmp is
    removed, nothing is cached, the run uses the library it built (one
    warning), and the build folder is gone."""
    from tmtcontrol.simulation import cache, rollout

    if rollout.compiler() is None:
        pytest.skip("no C compiler")
    monkeypatch.setenv("TMTCONTROL_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(cache, "open", _full_open(), raising=False)
    with pytest.warns(RuntimeWarning, match=r"disk holding the compile cache is full \(No space left on device\); "
                                            "this run's compiled code is not cached"):
        r = rollout.Rollout(toy_step(1.0), compile=True)
    assert r.how == "compiled"
    _check_runs(r)
    assert list((tmp_path / "cache").iterdir()) == []
    assert list(private_tmp.iterdir()) == []


def test_full_tmpfs_while_caching_a_library(small_disk, private_tmp, monkeypatch):
    from tmtcontrol.simulation import rollout

    if rollout.compiler() is None:
        pytest.skip("no C compiler")
    cache_dir = small_disk / "cache"
    cache_dir.mkdir()
    _fill(small_disk, leave=4096)                       # a library takes more than one page
    monkeypatch.setenv("TMTCONTROL_CACHE", str(cache_dir))
    with pytest.warns(RuntimeWarning, match="disk holding the compile cache is full"):
        r = rollout.Rollout(toy_step(2.0), compile=True)
    assert r.how == "compiled"
    _check_runs(r, 2.0)
    assert list(cache_dir.iterdir()) == [] and list(private_tmp.iterdir()) == []
