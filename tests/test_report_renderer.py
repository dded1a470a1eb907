"""The report without WeasyPrint's system libraries (issue 27.6): the PDF engine is
checked before anything is computed; `--format pdf` alone is refused (exit 2, one
line, nothing written); the default `html,pdf` writes the HTML and fails only the
PDF, saying so (exit 1)."""
import subprocess
import sys
import textwrap

import pytest

# a meta-path finder under which `import weasyprint` fails as on a machine without Pango (cffi's dlopen OSError)
NO_PANGO = textwrap.dedent("""
    import importlib.util, sys
    class NoPango:
        def find_spec(self, name, path=None, target=None):
            return importlib.util.spec_from_loader(name, self) if name == "weasyprint" else None
        def create_module(self, spec):
            return None
        def exec_module(self, module):
            raise OSError("cannot load library 'libpango-1.0-0': cannot open shared object file")
    sys.meta_path.insert(0, NoPango())
    from tmtcontrol.cli import main
    sys.exit(main(sys.argv[1:]))
""")


def _report(tmp_path, *args):
    return subprocess.run([sys.executable, "-c", NO_PANGO, "report", "paper", "--out", str(tmp_path / "r"), *args],
                          capture_output=True, text=True, timeout=900, cwd=tmp_path)


def test_pdf_only_without_its_engine_is_refused_before_computing(tmp_path):
    r = _report(tmp_path, "--format", "pdf")
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert lines[0].startswith("error: --format pdf:") and "libpango" in lines[0]
    assert "[1/" not in r.stderr and r.stdout == ""         # no stage ran: nothing was computed
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_html_and_pdf_without_the_pdf_engine_into_a_refused_folder_is_one_line(tmp_path):
    """The "writing report.html only" warning was printed before --out was
    checked: a folder that is not tmtcontrol's gave the warning and the
    refusal, two lines against the one-line rule."""
    theirs = tmp_path / "r"
    theirs.mkdir()
    (theirs / "notes.txt").write_text("a user's file")
    r = _report(tmp_path)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and lines[0].startswith("error: --out"), r.stderr
    assert [p.name for p in theirs.iterdir()] == ["notes.txt"] and r.stdout == ""


@pytest.mark.heavy
def test_html_and_pdf_without_the_pdf_engine_write_the_html_and_fail_the_pdf(tmp_path):
    r = _report(tmp_path)                                     # the default --format html,pdf
    assert r.returncode == 1, r.stderr
    err = r.stderr.strip().splitlines()
    assert err[0].startswith("warning: --format pdf:") and err[0].endswith("writing report.html only")
    assert err[-1].startswith("error: report.pdf was not written")
    assert (tmp_path / "r" / "report.html").is_file() and not (tmp_path / "r" / "report.pdf").exists()
