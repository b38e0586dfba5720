"""risktwin.evaluate gives `risktwin evaluate`'s document; a Python callable drives as a model
file giving the same actions; the library is read as the CLI reads it."""

import json

import numpy as np
import onnx
import pytest
from onnx import TensorProto, helper

import risktwin

CRUISE = [0.0, 0.3, 0.0]


def constant_onnx(path, action):
    """An ONNX driver of the driver interface whose action is `action` whatever it sees:
    obs [1, 24] -> obs·0 + action (exact in float32)."""
    graph = helper.make_graph(
        [helper.make_node("MatMul", ["obs", "zero"], ["none"]), helper.make_node("Add", ["none", "a"], ["action"])],
        "constant",
        [helper.make_tensor_value_info("obs", TensorProto.FLOAT, [1, 24])],
        [helper.make_tensor_value_info("action", TensorProto.FLOAT, [1, 3])],
        [
            helper.make_tensor("zero", TensorProto.FLOAT, [24, 3], [0.0] * 72),
            helper.make_tensor("a", TensorProto.FLOAT, [1, 3], action),
        ],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)], ir_version=8)
    for key, value in [("risktwin.observation_version", "1"), ("risktwin.decision_rate_hz", "20")]:
        entry = model.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.save(model, path)


def test_a_spec_gives_the_clis_document(risktwin_cli):
    doc = risktwin.evaluate("idm", seed=5, per_kind=2, threads=2)
    cli = json.loads(risktwin_cli("evaluate", "--driver", "idm", "--seed", "5", "--per-kind", "2", "--format", "json"))
    assert doc == cli
    assert doc["overall"]["driver"]["episodes"] == 10
    assert doc["confidence"] == 0.95


def test_a_callable_drives_as_a_model_file_with_the_same_actions(tmp_path):
    model = tmp_path / "cruise.onnx"
    constant_onnx(str(model), CRUISE)
    seen = []

    def cruise(obs):
        seen.append(obs)
        return CRUISE

    by_callable = risktwin.evaluate(cruise, seed=3, per_kind=2)
    by_model = risktwin.evaluate(str(model), seed=3, per_kind=2)
    assert by_callable["driver"] == "python:test_a_callable_drives_as_a_model_file_with_the_same_actions.<locals>.cruise"
    assert by_model["driver"].startswith(str(model) + "@")
    for key in ["overall", "by_kind", "episodes", "set"]:
        assert by_callable[key] == by_model[key], key
    assert all(o.dtype == np.float32 and o.shape == (24,) for o in seen)
    steps = sum(e["metrics"]["steps"] for e in by_callable["episodes"])
    assert len(seen) == steps
    assert by_callable["model_faults"] == 0
    assert risktwin.evaluate(cruise, seed=np.int64(3), per_kind=np.uint8(2))["episodes"] == by_callable["episodes"]
    huge = risktwin.evaluate(lambda obs: [0.0, 1e39, 0.0], seed=3, per_kind=2)  # beyond float32: clamped to 1
    assert huge["model_faults"] == 0 and huge["episodes"] == risktwin.evaluate(lambda obs: [0.0, 1.0, 0.0], seed=3, per_kind=2)["episodes"]
    by_path = risktwin.evaluate(model, seed=3, per_kind=2)  # a path object names the same file
    assert by_path["episodes"] == by_model["episodes"]
    braking = risktwin.evaluate(lambda obs: np.array([0, 0, 1.0]), seed=3, per_kind=2, label="brake")
    assert braking["driver"] == "brake"
    assert braking["episodes"] != by_callable["episodes"]


def test_a_non_finite_decision_drives_as_the_zero_action_and_is_counted(tmp_path):
    still = risktwin.evaluate(lambda obs: [0.0, 0.0, 0.0], seed=3, per_kind=1)
    broken = risktwin.evaluate(lambda obs: [float("nan"), 0.3, 0.0], seed=3, per_kind=1)
    assert broken["episodes"] == still["episodes"] and broken["overall"] == still["overall"]
    steps = sum(e["metrics"]["steps"] for e in broken["episodes"])
    assert broken["model_faults"] == steps > 0 and still["model_faults"] == 0


def test_a_library_evaluation_stores_outcomes_that_rank_by_label(tmp_path, risktwin_cli):
    risktwin_cli("scenarios", "generate", "--kind", "all", "--count", "2", "--seed", "4", "--db", "lib.db", "--format", "json", cwd=tmp_path)
    db = tmp_path / "lib.db"
    doc = risktwin.evaluate(lambda obs: CRUISE, library=db, label="cruise")
    library = risktwin.Library(db)
    ranked = library.rank(label="cruise")
    assert len(ranked) == doc["overall"]["driver"]["episodes"] == len(library.rank())
    cli = json.loads(risktwin_cli("scenarios", "rank", "--db", "lib.db", "--format", "json", cwd=tmp_path))
    assert library.rank() == cli
    first = library.scenario(ranked[0]["id"])
    assert first["spec"]["kind"] == ranked[0]["kind"]
    assert {o["label"] for o in first["outcomes"]} == {"idm", "cruise"}


def test_bad_drivers_and_arguments_raise_with_the_message(tmp_path):
    with pytest.raises(ValueError, match="unknown driver 'model.pt'"):
        risktwin.evaluate("model.pt")
    with pytest.raises(ValueError, match="missing.onnx"):
        risktwin.evaluate("missing.onnx")
    (tmp_path / "junk.onnx").write_bytes(b"not a model")
    with pytest.raises(ValueError, match="not an ONNX model"):
        risktwin.evaluate(str(tmp_path / "junk.onnx"))
    with pytest.raises(ValueError, match="replay"):
        risktwin.evaluate("replay")
    with pytest.raises(ValueError, match="per_kind"):
        risktwin.evaluate("idm", per_kind=0)
    with pytest.raises(ValueError, match="no scenario library"):
        risktwin.evaluate("idm", library=tmp_path / "none.db")
    with pytest.raises(ValueError, match="held-out set"):
        risktwin.evaluate("idm", library=tmp_path / "none.db", seed=2)
    with pytest.raises(ValueError, match="seed"):
        risktwin.evaluate("idm", seed=-1)
    with pytest.raises(ValueError, match="seed"):
        risktwin.evaluate("idm", seed=True)
    assert risktwin.RiskTwinError.__module__ == "risktwin._native"
    with pytest.raises(ValueError, match="per_kind"):
        risktwin.evaluate("idm", per_kind=2**64)
    with pytest.raises(ValueError, match="label"):
        risktwin.evaluate(lambda obs: CRUISE, library=tmp_path / "none.db")
    with pytest.raises(ValueError, match="returned 2 numbers"):
        risktwin.evaluate(lambda obs: [0.0, 0.0], per_kind=1)
    with pytest.raises(ValueError, match="SPEC"):
        risktwin.evaluate(42)
    with pytest.raises(ValueError, match="no scenario library"):
        risktwin.Library(tmp_path / "none.db")

    def broken(obs):
        raise ZeroDivisionError("the stack fell over")

    with pytest.raises(ZeroDivisionError, match="fell over"):
        risktwin.evaluate(broken, per_kind=1)
