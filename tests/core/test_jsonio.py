import json
import math
from pathlib import Path

import numpy as np

from gfb_env import jsonio


def _strict_loads(text: str):
    def reject(name):
        raise ValueError(f"non-standard JSON constant {name}")

    return json.loads(text, parse_constant=reject)


def test_non_finite_values_become_null_and_numpy_becomes_python():
    obj = {
        "nan": float("nan"),
        "inf": np.float64(np.inf),
        "arr": np.array([1.0, np.nan, -np.inf]),
        "int": np.int64(3),
        "flag": np.bool_(True),
        "nested": [{"x": (np.float32(0.5), None)}],
        "path": Path("results/x"),
    }
    out = _strict_loads(jsonio.dumps(obj))
    assert out == {
        "nan": None,
        "inf": None,
        "arr": [1.0, None, None],
        "int": 3,
        "flag": True,
        "nested": [{"x": [0.5, None]}],
        "path": "results/x",
    }


def test_dumps_writes_null_where_the_plain_json_module_writes_nan():
    # the reason for the module: the standard library writes tokens strict parsers reject; jsonio's
    # exact text for the same object has none of them
    obj = {"x": math.nan, "y": [-math.inf, np.float32("nan")], "z": 1.5}
    plain = json.dumps({"x": math.nan, "y": [-math.inf, math.nan], "z": 1.5})
    assert "NaN" in plain and "-Infinity" in plain
    text = jsonio.dumps(obj)
    assert text == '{"x": null, "y": [null, null], "z": 1.5}'
    assert _strict_loads(text) == {"x": None, "y": [None, None], "z": 1.5}
    assert jsonio.dumps(obj, indent=2).count("\n") == 7  # keyword arguments reach json.dumps


def test_write_json_round_trips(tmp_path):
    p = tmp_path / "s.json"
    jsonio.write_json(p, {"a": [1, 2.5, float("nan")]})
    assert _strict_loads(p.read_text()) == {"a": [1, 2.5, None]}
