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


def test_a_file_deleted_from_a_previous_output_does_not_stop_its_replacement(tmp_path):
    """Nothing of the user's is lost by replacing it (documented rule)."""
    out = commit(tmp_path / "o")
    (out / "sub" / "deeper" / "x.bin").unlink()
    commit(out, {"new.txt": b"n"})
    assert (out / "new.txt").read_bytes() == b"n" and not (out / "sub").exists()


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
    from tmtcontrol import cache
    from tmtcontrol.simulation import rollout

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


# -- item 3: litter is cleaned, the fallback cache reused, the cache bounded -----------------

HOLDER = """
import sys
from tmtcontrol.files import OutputFolder
f = OutputFolder(sys.argv[1])
(f.path / "half.csv").write_text("1,2")
print(f.path, flush=True)
sys.stdin.read()
"""


def _stagings(parent):
    return sorted(p.name for p in parent.iterdir() if p.name.startswith(".o.tmt-") and p.is_dir())


def test_staging_folders_of_killed_runs_are_cleaned_and_live_ones_kept(tmp_path):
    """A run killed with SIGKILL leaves its staging folder; the next run into
    the same target removes it, but never the staging folder of a run that is
    still alive."""
    import signal

    out = tmp_path / "o"
    live = subprocess.Popen([sys.executable, "-c", HOLDER, str(out)], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    doomed = subprocess.Popen([sys.executable, "-c", HOLDER, str(out)], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True)
    try:
        live_path = pathlib.Path(live.stdout.readline().strip())
        doomed_path = pathlib.Path(doomed.stdout.readline().strip())
        doomed.send_signal(signal.SIGKILL)
        doomed.wait()
        assert doomed_path.exists()                                       # the litter a SIGKILL leaves
        assert pathlib.Path(f"{doomed_path}.owner").exists()
        with OutputFolder(out) as mine:
            assert not doomed_path.exists() and live_path.exists()
            assert not pathlib.Path(f"{doomed_path}.owner").exists() and pathlib.Path(f"{live_path}.owner").exists()
            assert not any(p.name.startswith(".") for p in live_path.iterdir())   # the record is not an output
            assert (live_path / "half.csv").read_text() == "1,2"
            assert _stagings(tmp_path) == sorted([live_path.name, mine.path.name])
    finally:
        live.kill()
        live.wait()
        doomed.kill()
        doomed.wait()


def _fake_staging(parent, name, record):
    p = parent / name
    p.mkdir()
    (p / "part.csv").write_text("x")
    if record is not None:
        (parent / (name + ".owner")).write_text(json.dumps(record))
    return p


def test_a_reused_pid_or_another_host_is_told_apart(tmp_path):
    """The owner is recorded as (host, boot, pid, start time): a record with
    this process' pid but another start time is a dead owner whose pid was
    reused (cleaned); this process' own record, another host's, or a folder
    without a record are left alone; a previous output moved aside by a
    commit that died (``.o.tmt-X.old`` without ``.o.tmt-X``) is cleaned."""
    from tmtcontrol.files import _owner_record

    me = _owner_record()
    assert me["pid"] == os.getpid() and me["start"] is not None
    reused = _fake_staging(tmp_path, ".o.tmt-reused", {**me, "start": str(int(me["start"]) + 1)})
    other_boot = _fake_staging(tmp_path, ".o.tmt-reboot", {**me, "boot": "another-boot"})
    alive = _fake_staging(tmp_path, ".o.tmt-alive", me)
    elsewhere = _fake_staging(tmp_path, ".o.tmt-elsewhere", {**me, "host": me["host"] + "-other", "pid": 2**22 + 7})
    unknown = _fake_staging(tmp_path, ".o.tmt-unknown", None)
    aside = _fake_staging(tmp_path, ".o.tmt-gone.old", None)
    aside_live = _fake_staging(tmp_path, ".o.tmt-alive.old", None)
    other_target = _fake_staging(tmp_path, ".p.tmt-reused", {**me, "start": "1"})
    orphan = tmp_path / ".o.tmt-committed.owner"                  # its folder was committed, then a crash
    orphan.write_text(json.dumps(me))
    with OutputFolder(tmp_path / "o"):
        pass
    assert not orphan.exists() and not (tmp_path / ".o.tmt-reused.owner").exists()
    assert (tmp_path / ".o.tmt-alive.owner").exists()
    assert not reused.exists() and not other_boot.exists() and not aside.exists()
    assert alive.exists() and elsewhere.exists() and unknown.exists() and aside_live.exists()
    assert other_target.exists()                                  # only litter of the same target is touched


def test_unwritable_cache_reuses_one_private_fallback_folder(tmp_path, private_tmp, monkeypatch):
    from tmtcontrol import cache
    from tmtcontrol.simulation import rollout

    if rollout.compiler() is None:
        pytest.skip("no C compiler")
    blocker = tmp_path / "file"
    blocker.write_text("x")
    monkeypatch.setenv("TMTCONTROL_CACHE", str(blocker / "cache"))      # below a regular file
    with pytest.warns(RuntimeWarning, match="cannot write the compile cache .* kept in .*tmtcontrol-cache-"):
        first = rollout.Rollout(toy_step(3.0), compile=True)
    fallback = cache.fallback_dir()
    assert first.how == "compiled" and first.library.parent == fallback
    assert (fallback.stat().st_mode & 0o777) == 0o700
    second = rollout.Rollout(toy_step(3.0), compile=True)             # the next run: from the fallback
    assert second.how == "cached" and second.library == first.library
    _check_runs(second, 3.0)
    assert sorted(p.name for p in private_tmp.iterdir()) == [fallback.name]
    # a fallback folder others could write is never used (it could hold anyone's code)
    fallback.chmod(0o777)
    with pytest.warns(RuntimeWarning, match="this run's compiled code is not cached"):
        third = rollout.Rollout(toy_step(3.0), compile=True)
    assert third.how == "compiled" and not str(third.library).startswith(str(fallback))
    _check_runs(third, 3.0)
    assert sorted(p.name for p in private_tmp.iterdir()) == [fallback.name]


def _fake_library(folder, name, size, used):
    lib = folder / f"{name}_chunk_{hashlib.sha256(name.encode()).hexdigest()[:20]}.so"
    lib.write_bytes(b"\0" * size)
    lib.with_suffix(".json").write_text("{}")
    os.utime(lib, (used, used))
    return lib


def test_prune_keeps_the_most_recently_used_libraries_within_the_bound(tmp_path):
    """Five fake libraries of 100 kB used 1 to 5 days ago, a bound of 350 kB,
    an age limit of 30 days: the three most recent stay (3 x 100 kB plus
    sidecars), the rest go, then a library unused for 40 days goes even under
    the size bound; staged files older than an hour go; files tmtcontrol does
    not name, and the library just built, always stay."""
    from tmtcontrol.cache import prune

    now = 1.8e9
    libs = [_fake_library(tmp_path, f"law{i}", 100_000, now - (i + 1) * 86400) for i in range(5)]
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    stale = tmp_path / f".{libs[0].name}.123.tmp"
    fresh = tmp_path / f".{libs[1].name}.456.tmp"
    for p, age in ((stale, 7200), (fresh, 60)):
        p.write_bytes(b"partial")
        os.utime(p, (now - age, now - age))
    keep = libs[4]                                            # the oldest, but the one just built
    removed = prune(tmp_path, keep=(keep,), max_bytes=350_000, max_age_days=30, now=now)
    assert sorted(removed) == sorted(libs[3:4])
    assert all(p.exists() and p.with_suffix(".json").exists() for p in libs[:3] + [keep])
    assert not libs[3].exists() and not libs[3].with_suffix(".json").exists()
    assert notes.read_text() == "mine" and fresh.exists() and not stale.exists()
    old = _fake_library(tmp_path, "old", 10, now - 40 * 86400)
    assert prune(tmp_path, max_bytes=10**9, max_age_days=30, now=now) == [old]


def test_cache_info_says_when_the_cache_is_a_file(tmp_path, monkeypatch, capsys):
    """Regression (review 5 leftover): ``TMTCONTROL_CACHE`` naming a file gave
    ``cache --info`` "0 libraries" as if it were an empty folder; it says the
    path is not a folder, and the file is left as it was."""
    f = tmp_path / "a-file"
    f.write_text("mine")
    monkeypatch.setenv("TMTCONTROL_CACHE", str(f))
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "no-fallback"))
    assert main(["cache", "--info"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == f"cache: {f}: not a folder: nothing is cached there; compiled code goes to the per-user fallback"
    assert f.read_text() == "mine"


def test_cache_info_and_clear(tmp_path, monkeypatch, capsys):
    """``tmtcontrol cache --info`` names the folder, counts the libraries and
    their size; ``--clear`` removes only tmtcontrol's files."""
    monkeypatch.setenv("TMTCONTROL_CACHE", str(tmp_path))
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "no-fallback"))
    for i in range(2):
        _fake_library(tmp_path, f"law{i}", 2**20, 1.7e9)
    (tmp_path / "notes.txt").write_text("mine")
    (tmp_path / "law0_chunk_other.so").write_text("not tmtcontrol's name")
    from tmtcontrol.cache import load_result, store_result

    assert store_result("limit", "a key", {"limit": 1.0})                 # an analysis result, in results/
    from tmtcontrol.cache import compile_lock

    with compile_lock("law0_chunk_" + "a" * 20 + ".so"):                  # a compile's lock: removed after
        assert [p.name for p in (tmp_path / "locks").iterdir()] == ["law0_chunk_" + "a" * 20 + ".so.lock"]
    assert not (tmp_path / "locks").exists()
    (tmp_path / "locks").mkdir()                                          # one left by a killed compile
    (tmp_path / "locks" / ("law1_chunk_" + "b" * 20 + ".so.lock")).write_text("")
    (tmp_path / "locks" / "mine.lock").write_text("not tmtcontrol's name")
    (tmp_path / "results" / "result_mine.json").write_text("not tmtcontrol's name")
    assert main(["cache", "--info"]) == 0
    out = capsys.readouterr().out.splitlines()
    size = 2 * 2**20 + 4 + len(next((tmp_path / "results").glob("result_*[0-9a-f].json")).read_bytes())
    assert out[0] == f"cache: {tmp_path}: 2 libraries, 1 analysis result, {size / 2**20:,.1f} MiB"
    assert main(["cache", "--clear"]) == 0
    assert capsys.readouterr().out == "removed 2 compiled libraries and 1 analysis result (2.0 MiB)\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["law0_chunk_other.so", "locks", "notes.txt", "results"]
    assert [p.name for p in (tmp_path / "locks").iterdir()] == ["mine.lock"]
    assert [p.name for p in (tmp_path / "results").iterdir()] == ["result_mine.json"]
    assert load_result("limit", "a key") is None
    assert main(["cache"]) == 0 and capsys.readouterr().out.startswith(
        f"cache: {tmp_path}: 0 libraries, 0 analysis results, 0.0 MiB")


# -- item 4: concurrent commits into one target ----------------------------------------------

WRITER = """
import os, sys
from tmtcontrol.files import OutputFolder
out, n = sys.argv[1], int(sys.argv[2])
for i in range(n):
    with OutputFolder(out) as f:
        (f.path / "sub").mkdir()
        (f.path / "sub" / "run.txt").write_text(f"{os.getpid()} {i}")
        (f.path / "summary.json").write_text('{"i": %d}' % i)
        f.commit("writer")
print("ok", flush=True)
"""


def test_four_processes_committing_into_one_target_all_succeed(tmp_path):
    """4 processes x 25 commits into the same --out: every commit succeeds
    (each replaces a tmtcontrol output; the last one wins), the result is one
    complete output whose manifest checks, and nothing is left beside it."""
    out = tmp_path / "o"
    procs = [subprocess.Popen([sys.executable, "-c", WRITER, str(out), "25"], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(4)]
    results = [p.communicate(timeout=300) for p in procs]
    for p, (stdout, stderr) in zip(procs, results):
        assert p.returncode == 0 and stdout == "ok\n" and stderr == "", stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o"]
    m = json.loads((out / MANIFEST).read_text())
    assert set(m["files"]) == {"sub/run.txt", "summary.json"} and m["folders"] == ["sub"]
    pid, i = (out / "sub" / "run.txt").read_text().split()
    assert int(i) == 24 and int(pid) in {p.pid for p in procs}      # the last commit of one of them
    with OutputFolder(out):                                          # and it is a valid previous output
        pass


def test_the_check_and_the_commit_hold_the_parent_folders_lock(tmp_path, monkeypatch):
    """The check, the staging folder's creation and the rename happen under an
    exclusive flock of the target's parent folder."""
    import fcntl

    import tmtcontrol.files as files

    calls = []
    real = fcntl.flock

    def flock(fd, op):
        calls.append((os.path.realpath(f"/proc/self/fd/{fd}"), op))
        return real(fd, op)

    monkeypatch.setattr(files.fcntl, "flock", flock)
    with OutputFolder(tmp_path / "a" / "o") as f:
        assert calls == [(str(tmp_path / "a"), fcntl.LOCK_EX)]
        f.commit()
    assert calls == [(str(tmp_path / "a"), fcntl.LOCK_EX)] * 2


# -- item 5: a failed run leaves no parent folders it created ---------------------------------

def test_a_failed_run_removes_the_parent_folders_it_created(tmp_path, monkeypatch, capsys):
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "mine.txt").write_text("mine")
    with pytest.raises(RuntimeError):
        with OutputFolder(tmp_path / "a" / "b" / "c" / "out"):
            assert (tmp_path / "a" / "b" / "c").is_dir()
            raise RuntimeError("the run failed")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a"]          # a/ was there before: kept
    assert sorted(p.name for p in (tmp_path / "a").iterdir()) == ["mine.txt"]
    # through the CLI: a run that fails after the folder was made (here, a full disk)
    import tmtcontrol.simulation.output as output

    def full(res, path, **kw):
        raise _enospc(str(path))

    monkeypatch.setattr(output, "write_timeseries", full)
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", *SHORT, "--out", "x/y/z"]) == 3
    assert "x/y/z" in capsys.readouterr().err and not (tmp_path / "x").exists()
    # a successful run keeps them, of course
    commit(tmp_path / "p" / "q", {"f": b"1"})
    assert (tmp_path / "p" / "q" / "f").read_bytes() == b"1"


def test_an_output_name_too_long_is_one_line(tmp_path):
    with pytest.raises(OutputError, match=r"^--out: cannot write .* \(File name too long\)$"):
        OutputFolder(tmp_path / ("n" * 300))
    assert list(tmp_path.iterdir()) == []


# -- item 6: the docs quote the messages the code prints ----------------------------------------

def test_docs_outputs_quote_the_messages_as_printed(tmp_path, monkeypatch):
    """Each example line in docs/outputs.md is regenerated here from the code."""
    from tmtcontrol import apply_overrides, paper_scenario
    from tmtcontrol.simulation.scenario import ScenarioError
    from tmtcontrol.simulation.simulator import check_run_size

    docs = (pathlib.Path(__file__).parents[1] / "docs" / "outputs.md").read_text()
    with pytest.raises(ScenarioError) as err:
        check_run_size(apply_overrides(paper_scenario(), ["trajectory.cycles=1000"]))
    assert f"error: {err.value}\n" in docs
    monkeypatch.chdir(tmp_path)
    commit(pathlib.Path("cmp"), {"tmt/timeseries.csv": b"1"})
    (tmp_path / "cmp" / "tmt" / "my_analysis.txt").write_text("notes")
    with pytest.raises(OutputError) as err:
        OutputFolder("cmp")
    assert f"error: {err.value}\n" in docs
    with pytest.raises(OutputNotSaved) as err:
        with OutputFolder("tmt-results"):
            raise _enospc()
    assert f"error: {err.value}\n" in docs


def test_gitignore_lists_every_default_output_folder():
    """The defaults of every command's --out (from the parser) are ignored by git."""
    from tmtcontrol.cli import build_parser

    ignored = (pathlib.Path(__file__).parents[1] / ".gitignore").read_text().split()
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    defaults = {p.get_default("out") for p in sub.choices.values()} - {None}
    assert {"tmt-results", "tmt-compare", "tmt-sweep", "tmt-report"} <= defaults
    assert {f"{d}/" for d in defaults} <= set(ignored), defaults


SWEEP = """scenario = "paper"
[grid]
"environment.stiffness.values" = [[2000.0], [20000.0]]
"trajectory.cycles" = [0.1]
"""


@pytest.mark.heavy
@pytest.mark.parametrize("command", ["sweep", "report"])
def test_full_tmpfs_during_sweep_and_report(small_disk, tmp_path, command):
    """The same for the two other long commands (sweep: its partial folder
    and its results; report: its HTML written by its second process). A
    sweep's previous output stays; a report's first run meets the full disk."""
    (tmp_path / "s.toml").write_text(SWEEP)
    out = small_disk / "o"
    args = CLI + (["sweep", str(tmp_path / "s.toml"), "--no-plots", "--out", str(out)] if command == "sweep" else
                  ["report", "--set", "trajectory.cycles=0.5", "--format", "html", "--out", str(out)])
    if command == "sweep":
        assert subprocess.run(args, capture_output=True, text=True).returncode == 0
    _fill(small_disk, leave=2000 if command == "sweep" else 200_000)
    before = snapshot(small_disk)
    r = subprocess.run(args, capture_output=True, text=True)
    assert r.returncode == 3, r.stderr
    errors = [line for line in r.stderr.splitlines() if line.startswith("error")]
    assert errors == [f"error: --out: no space left on the disk holding {out} (No space left on device); free "
                      f"some space and run again (the results were not saved; {out} was left as it was)"]
    assert "Traceback" not in r.stderr
    assert snapshot(small_disk) == before and litter(small_disk) == []


def test_a_signal_during_the_commits_renames_never_loses_the_previous_output(tmp_path, monkeypatch):
    """Ctrl-C arriving between moving the previous output aside and renaming
    the new one into place is acted on after both renames: the target is
    then the new, complete output (never missing, never the old one lost)."""
    import signal

    import tmtcontrol.files as files

    out = commit(tmp_path / "o")
    real = os.replace
    calls = []

    def replace(a, b):
        real(a, b)
        calls.append(b)
        if len(calls) == 1:                                   # the previous output is aside now
            os.kill(os.getpid(), signal.SIGINT)

    previous = files.install_signal_handlers()
    try:
        monkeypatch.setattr(files.os, "replace", replace)
        with pytest.raises(files.Interrupted):
            with OutputFolder(out) as folder:
                (folder.path / "new.txt").write_text("complete")
                folder.commit()
    finally:
        files.restore_signal_handlers(previous)
    assert len(calls) == 2 and (out / "new.txt").read_text() == "complete"
    assert litter(tmp_path) == []


@pytest.mark.parametrize("delivery", ["process", "another thread"])
@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_a_signal_while_the_staging_folder_is_made_leaves_nothing(tmp_path, monkeypatch, sig, delivery):
    """The signal lands inside ``mkdtemp``, after the folder exists and before
    its name is returned (the window a CI run hit: SIGTERM sent as soon as the
    staging folder appeared left it behind). It is acted on once the folder is
    recorded, so the constructor's clean-up removes it. "another thread": the
    kernel handed the signal to a thread that does not block it (a BLAS or
    watchdog thread), and the main thread runs the Python handler at its next
    instruction (``_thread.interrupt_main`` does exactly that); blocking the
    signal in the main thread alone does not hold it then."""
    import _thread
    import signal
    import tempfile

    import tmtcontrol.files as files

    real = tempfile.mkdtemp
    signum = getattr(signal, sig)

    def mkdtemp(*args, **kw):
        path = real(*args, **kw)
        if delivery == "process":
            os.kill(os.getpid(), signum)
        else:
            _thread.interrupt_main(signum)
        return path                                       # the handler runs before this line

    previous = files.install_signal_handlers()
    try:
        monkeypatch.setattr(files.tempfile, "mkdtemp", mkdtemp)
        with pytest.raises(files.Interrupted) as info:
            OutputFolder(tmp_path / "new" / "o")
    finally:
        files.restore_signal_handlers(previous)
    assert info.value.signum == signum
    assert list(tmp_path.iterdir()) == [] and not [p for p in files._unsaved if tmp_path in p.parents]


def test_a_signal_a_finished_command_remembered_does_not_stop_a_later_output(tmp_path):
    """A signal recorded under the CLI's handlers (one CasADi swallowed) was
    acted on by that command; once the handlers are restored it no longer
    stops an output folder made in the same process (a notebook calling
    ``main`` and then the Python API)."""
    import signal

    import tmtcontrol.files as files

    previous = files.install_signal_handlers()
    files._pending.append(signal.SIGINT)
    files.restore_signal_handlers(previous)
    assert signal.getsignal(signal.SIGINT) is previous[0] and signal.getsignal(signal.SIGTERM) is previous[1]
    folder = OutputFolder(tmp_path / "o")
    (folder.path / "a.txt").write_text("x")
    assert folder.commit() == tmp_path / "o" and (tmp_path / "o" / "a.txt").read_text() == "x"


def test_a_signal_between_the_constructor_and_with_is_cleaned_by_the_cli(tmp_path, monkeypatch, capsys):
    """An interruption after ``OutputFolder(...)`` returned and before its
    ``with`` block began (its own clean-up cannot run): the command line's
    net removes the staging folder, and exits 130 with one line."""
    import tmtcontrol.files as files

    def enter(self):
        raise files.Interrupted()

    monkeypatch.setattr(files.OutputFolder, "__enter__", enter)
    code = main(["simulate", *SHORT, "--out", str(tmp_path / "o")])
    assert code == 130 and "interrupted" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == [] and not [p for p in files._unsaved if tmp_path in p.parents]


def test_the_cli_net_leaves_staging_folders_made_before_it_alone(tmp_path):
    """A staging folder a caller made before the command ran is not the
    command's to remove."""
    from tmtcontrol.files import staging_removed_on_exit

    mine = OutputFolder(tmp_path / "mine")
    try:
        with staging_removed_on_exit():
            inner = OutputFolder(tmp_path / "inner")
        assert mine.path.is_dir() and not inner.path.exists()
    finally:
        mine.discard()


def test_compile_litter_in_the_temporary_folder_is_removed_after_a_day(private_tmp):
    """Build folders of a killed compile (tmtcontrol-cg-*) and the per-run
    library folders of older versions (tmtcontrol-lib-*) older than a day
    go; younger ones (a compile under way), the per-user fallback and
    anything else stay; ``cache --clear`` removes them whatever their age."""
    import time

    from tmtcontrol.cache import clear_cache, fallback_cache, prune_temporary

    now = time.time()                          # clear_cache looks at the real clock
    made = {}
    for name, age_h in (("tmtcontrol-cg-abc123", 30), ("tmtcontrol-lib-x_9", 48), ("tmtcontrol-cg-fresh", 2),
                        ("tmtcontrol-other", 99), ("mine-tmtcontrol-cg-1", 99)):
        p = private_tmp / name
        p.mkdir()
        (p / "lib.so").write_bytes(b"x")
        os.utime(p, (now - age_h * 3600, now - age_h * 3600))
        made[name] = p
    fallback = fallback_cache()
    os.utime(fallback, (now - 99 * 3600, now - 99 * 3600))
    assert prune_temporary(now=now) == 2
    assert sorted(p.name for p in private_tmp.iterdir()) == sorted(
        ["tmtcontrol-cg-fresh", "tmtcontrol-other", "mine-tmtcontrol-cg-1", fallback.name])
    clear_cache()
    assert sorted(p.name for p in private_tmp.iterdir()) == sorted(
        ["tmtcontrol-other", "mine-tmtcontrol-cg-1", fallback.name])


# -- the shell's own folder is never replaced ----------------------------------------------


def test_out_dot_in_an_empty_current_folder_is_refused(tmp_path):
    """``--out .`` in an empty folder: the folder is empty, so it would count as
    replaceable, but replacing it leaves the user's shell in a removed folder.
    Refused in one line naming --out, exit 2, the folder (same inode) still empty."""
    here = tmp_path / "work"
    here.mkdir()
    inode = here.stat().st_ino
    r = subprocess.run(CLI + ["simulate", *SHORT, "--out", "."], cwd=here, capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: --out: . is the current folder"), lines
    assert here.stat().st_ino == inode and list(here.iterdir()) == [] and r.stdout == ""


def test_a_previous_output_holding_the_current_folder_is_refused(tmp_path, monkeypatch):
    """A user who ``cd``s into a subfolder of a previous output and names the
    output itself: replaceable by its manifest, but it holds the current folder."""
    out = commit(tmp_path / "o")
    monkeypatch.chdir(out / "sub" / "deeper")
    before = snapshot(out)
    with pytest.raises(OutputError, match=r"^--out: \.\./\.\. is the current folder or holds it"):
        OutputFolder("../..")
    monkeypatch.chdir(out)
    with pytest.raises(OutputError, match=r"^--out: \. is the current folder or holds it"):
        OutputFolder(".")
    assert snapshot(out) == before and litter(tmp_path) == []
    monkeypatch.chdir(tmp_path)            # from outside, the same folder is replaced as before
    commit("o")
    assert snapshot(out) == before


def test_a_failed_first_commit_is_not_saved_in_one_line_and_puts_nothing_in_place(tmp_path, monkeypatch):
    """The staging folder cannot be renamed onto a new target (EACCES, no
    previous output): OutputNotSaved naming the flag, no target, and no
    attempt to put back a previous output that never existed (that attempt
    itself would fail with FileNotFoundError instead of the one line)."""
    from tmtcontrol import files

    out = tmp_path / "results"
    real_replace = os.replace
    calls = []

    def refusing(src, dst):
        calls.append((os.fspath(src), os.fspath(dst)))
        if os.fspath(dst) == str(out):
            raise OSError(errno.EACCES, "Permission denied")
        return real_replace(src, dst)

    with pytest.raises(OutputNotSaved, match="--out: cannot write") as err:
        with OutputFolder(out, "--out") as staging:
            (staging.path / "a.txt").write_text("x")
            monkeypatch.setattr(files.os, "replace", refusing)
            staging.commit()
    assert "\n" not in str(err.value)
    assert not out.exists()
    assert [dst for _, dst in calls] == [str(out)]          # one attempt, nothing put back


@pytest.mark.parametrize("kind", ["link", "other"])
def test_a_link_or_a_fifo_in_the_staging_folder_is_refused_not_hashed(tmp_path, kind):
    """tmtcontrol's writers write files and folders only: anything else in a
    staging folder at commit (a symbolic link, which hashing would follow
    out of the folder; a FIFO, whose read would block) is an OutputError
    naming it, and nothing is committed."""
    out = tmp_path / "results"
    target = tmp_path / "elsewhere.txt"
    target.write_text("not ours")
    with pytest.raises(OutputError, match=f"a {kind} in the output"):
        with OutputFolder(out, "--out") as staging:
            (staging.path / "a.txt").write_text("x")
            if kind == "link":
                (staging.path / "b").symlink_to(target)
            else:
                os.mkfifo(staging.path / "b")
            staging.commit()
    assert not out.exists()


def test_an_out_below_a_file_says_the_file_is_not_a_folder(tmp_path, capsys):
    """Regression (review 5): ``--out FILE/sub`` said "(File exists)"; the line names
    the file on the way, which is left as it was."""
    from tmtcontrol.cli import main

    (tmp_path / "o").write_text("foreign")
    assert main(["analyze", "--m", "1", "--b", "60", "--k", "100", "--ke", "1000",
                 "--plot", str(tmp_path / "o" / "x")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"error: --plot: cannot write {tmp_path / 'o' / 'x'} ({tmp_path / 'o'} is not a folder)", err
    assert (tmp_path / "o").read_text() == "foreign" and sorted(p.name for p in tmp_path.iterdir()) == ["o"]
