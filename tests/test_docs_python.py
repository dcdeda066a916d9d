"""docs/python.md: every Python block runs, in order, as a reader would paste it."""

from __future__ import annotations

import re
import textwrap
import warnings

import numpy as np
import pytest

import attica

from helpers import ROOT


def test_python_blocks_run() -> None:
    text = (ROOT / "docs" / "python.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert len(blocks) >= 6
    rec = attica.simulate(attica.SimConfig(duration=20.0, rate=100.0, seed=2))
    ns: dict[str, object] = {"attica": attica, "np": np, "gyr": rec.gyr, "acc": rec.acc}
    ns["f"] = attica.Filter("ars", 0.01)
    ns["k"] = 10
    with warnings.catch_warnings():
        warnings.simplefilter("error", attica.UnitWarning)  # the examples use the right units
        for block in blocks:
            lines = []
            for line in block.splitlines():
                if "# SettingsError" in line:  # a line the text says raises
                    code = line.split("#")[0].strip()
                    lines += ["with pytest.raises(attica.SettingsError):", f"    {code}"]
                else:
                    lines.append(line)
            code = textwrap.dedent("\n".join(lines))
            exec(compile(code, "docs/python.md", "exec"), {**ns, "pytest": pytest}, ns)
        warnings.simplefilter("ignore", attica.UnitWarning)
    assert isinstance(ns["out"], np.ndarray)
