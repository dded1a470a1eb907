"""Regenerate the interface tables of docs/deploy.md from the exported structs' field tables.

Each ``<!-- table:NAME ... -->`` ... ``<!-- /table -->`` block is replaced by
the Markdown table of the fields the C structs are written from
(``tmtcontrol.export.generate``): the 3-joint position task's (the PUMA's)
and, for the ``arm-*`` blocks, the fields a 6-D task (the UR5's six joints)
changes or adds. ``tests/test_export.py`` and ``tests/test_export_6d.py``
fail when the doc and the code drift apart. Run: ``python benchmarks/deploy_tables.py``.
"""

import pathlib
import re

from tmtcontrol.control.laws import get_law
from tmtcontrol.export import generate

DOC = pathlib.Path(__file__).resolve().parents[1] / "docs" / "deploy.md"


def tables() -> dict:
    tmt = get_law("tmt")
    three = {f.name for f in generate.param_fields(tmt, 3)}
    arm_meas = generate.measurement_fields(6)[:2]
    arm_diag = tuple(f for f in generate.diagnostic_fields(6) if f.name in ("e_o",))
    arm_params = tuple(f for f in generate.param_fields(tmt, 7) if f.name not in three)
    return {"measurement": generate.measurement_fields(3), "command": generate.command_fields(True, 3),
            "diagnostics": generate.diagnostic_fields(3), "params": generate.param_fields(tmt, 3),
            "arm-measurement": arm_meas, "arm-command": generate.command_fields(True, 6),
            "arm-diagnostics": arm_diag, "arm-params": arm_params}


def main() -> None:
    text = DOC.read_text(encoding="utf-8")
    for name, fields in tables().items():
        pattern = re.compile(r"(<!-- table:" + re.escape(name) + r" [^\n]*-->\n)(.*?)(<!-- /table -->)", re.S)
        text, n = pattern.subn(lambda m: m.group(1) + generate._md_table(fields) + "\n" + m.group(3), text)
        assert n == 1, name
    DOC.write_text(text, encoding="utf-8")
    print(f"wrote {len(tables())} tables into {DOC}")


if __name__ == "__main__":
    main()
