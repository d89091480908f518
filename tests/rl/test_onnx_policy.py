"""A network sent as ONNX is checked before it is kept, and decides as its graph says: the
argmax of its logits, or the actions it gives, for a batch of observations in one call; what
it answers is checked at every call, where it is made."""

from __future__ import annotations

import numpy as np
import pytest

from nanonav.rl.graph import (
    METADATA_ACTIONS,
    METADATA_OBSERVATION,
    InvalidModel,
    model_labels,
)
from nanonav.rl.onnx_policy import NetworkPolicy, check_model, trial_observations
from tests.rl import models

LIMIT = 700_000


def test_an_mlp_decides_the_argmax_of_its_logits_for_every_row_in_one_call() -> None:
    rows = np.random.default_rng(0).normal(size=(500, 7))
    w1, b1, w2, b2 = models.mlp_weights(7, 4, seed=2)
    expected = np.argmax(np.maximum(rows.astype(np.float32) @ w1 + b1, 0) @ w2 + b2, axis=1)
    with NetworkPolicy(models.mlp(7, 4, seed=2), 7, 4, max_bytes=LIMIT) as policy:
        assert policy.info.output == "logits" and policy.info.opset == models.OPSET
        chosen = policy(rows)
    assert chosen.dtype == np.int64 and chosen.shape == (500,)
    assert np.array_equal(chosen, expected)
    assert len(set(chosen.tolist())) > 1  # the rows do lead to different actions


def test_a_model_that_answers_actions_is_run_as_it_answers() -> None:
    rows = np.zeros((3, 7))
    rows[0, 2], rows[1, 1], rows[2, 0] = 1.0, 1.0, 1.0
    with NetworkPolicy(models.argmax_actions(7, 4), 7, 4, max_bytes=LIMIT) as policy:
        assert policy.info.output == "actions"
        assert policy(rows).tolist() == [2, 1, 0]


def test_labels_come_from_the_models_metadata_when_it_has_them() -> None:
    plain = models.always(7, 4, 1)
    assert model_labels(plain, max_bytes=LIMIT) == (None, None)
    named = models.always(7, 4, 1, metadata={METADATA_OBSERVATION: '["a", "b"]',
                                             METADATA_ACTIONS: '["x"]'})  # fmt: skip
    assert model_labels(named, max_bytes=LIMIT) == (["a", "b"], ["x"])
    broken = models.always(7, 4, 1, metadata={METADATA_ACTIONS: "{not json"})
    with pytest.raises(InvalidModel, match=r"'nanonav\.actions' is not a list of labels"):
        model_labels(broken, max_bytes=LIMIT)


@pytest.mark.parametrize(
    ("data", "width", "actions", "message"),
    [
        (b"", 7, 4, "not an ONNX model"),
        (b"\x08\x07garbage that is not protobuf \xff\xff", 7, 4, "not an ONNX model"),
        (models.mlp(7, 4), 5, 4, r"has the shape \['batch', 7\]: it must be \(batch, 5\)"),
        (models.mlp(7, 4), 7, 6, r"logits must be \(batch, 6\), one per action"),
        (models.mlp(7, 4, opset=7), 7, 4, "opset is 7: it must lie between 9 and"),
        (models.custom_operator(7, 4), 7, 4, "imports the operator set 'com.example'"),
        (models.external_weights(7, 4), 7, 4, "keeps its data outside the model"),
        (models.kept_alive(7, 4, summed_by="Add"), 7, 4,
         r"node '#6' \(Add\): the model holds 280,000, over the cap of 262,144, bytes"),
        (models.argmax_actions(7, 4, favourite=3), 7, 3,
         r"answers an action outside 0\.\.2 for a zero observation \(a trial run\)"),
        (models.far_actions(7), 7, 4, "answers an action outside 0..3 for a zero observation"),
    ],
)  # fmt: skip
def test_a_model_that_cannot_decide_is_refused_saying_why(
    data: bytes, width: int, actions: int, message: str
) -> None:
    with pytest.raises(InvalidModel, match=message):
        check_model(data, width, actions, max_bytes=LIMIT)


def test_a_fixed_batch_a_second_input_and_the_size_limit_are_refused() -> None:
    import onnx
    from onnx import TensorProto, helper

    fixed = onnx.load_model_from_string(models.always(7, 4, 0))
    fixed.graph.input[0].type.tensor_type.shape.dim[0].ClearField("dim_param")
    fixed.graph.input[0].type.tensor_type.shape.dim[0].dim_value = 1
    with pytest.raises(InvalidModel, match="has a batch of exactly 1"):
        check_model(fixed.SerializeToString(), 7, 4, max_bytes=LIMIT)
    two = onnx.load_model_from_string(models.always(7, 4, 0))
    two.graph.input.append(helper.make_tensor_value_info("memory", TensorProto.FLOAT, [1, 3]))
    with pytest.raises(InvalidModel, match="is neither the observation nor a memory"):
        check_model(two.SerializeToString(), 7, 4, max_bytes=LIMIT)
    data = models.mlp(7, 4, hidden=64)
    with pytest.raises(InvalidModel, match=f"takes {len(data)} bytes, over the limit of 1024"):
        check_model(data, 7, 4, max_bytes=1024)


def test_a_batch_larger_than_one_call_takes_is_run_in_parts(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from nanonav.rl import onnx_policy

    rows = np.random.default_rng(1).normal(size=(1000, 7))
    with NetworkPolicy(models.mlp(7, 4, seed=3), 7, 4, max_bytes=LIMIT) as policy:
        whole = policy(rows)
        monkeypatch.setattr(onnx_policy, "INFERENCE_ROWS", 64)
        assert np.array_equal(policy(rows), whole)
        assert policy(np.zeros((0, 7))).shape == (0,)


def test_a_recurrent_network_carries_each_rows_memory_until_it_forgets() -> None:
    rows = np.zeros((3, 7))
    with NetworkPolicy(models.counter(7, 4), 7, 4, max_bytes=LIMIT) as policy:
        assert policy.remembers and [m.input_name for m in policy.info.memory] == ["memory_in"]
        assert [policy(rows).tolist() for _ in range(5)] == [[0] * 3] * 3 + [[1] * 3] * 2
        policy.forget()
        assert policy(rows).tolist() == [0, 0, 0]
        assert policy(np.zeros((5, 7))).tolist() == [0] * 5  # other rows: other robots, afresh


def test_an_answer_outside_the_action_set_is_refused_where_it_is_made() -> None:
    """A model that passes its trial run (its first decision is action 1) and then answers
    one past the last action: the call that answers it raises, naming the action."""
    rows = np.zeros((3, 7))
    with NetworkPolicy(models.counting_past(7), 7, 4, max_bytes=LIMIT) as policy:
        assert [policy(rows).tolist() for _ in range(3)] == [[1] * 3, [2] * 3, [3] * 3]
        with pytest.raises(ValueError, match=r"answers an action outside 0\.\.3 for a zero "
                                             r"observation$"):  # fmt: skip
            policy(rows)


def test_the_trial_observations_are_zeros_ones_and_draws_of_two_scales() -> None:
    rows = trial_observations(5)
    assert rows.dtype == np.float32 and rows.shape == (8, 5)
    assert not rows[:2].any() and (rows[2] == 1).all() and (rows[3] == -1).all()
    assert 1 < np.abs(rows[4:6]).max() < 5 and np.abs(rows[6:]).max() > 10


def test_a_memory_not_given_back_is_refused() -> None:
    import onnx

    broken = onnx.load_model_from_string(models.counter(7, 4))
    del broken.graph.output[1]
    with pytest.raises(InvalidModel, match="gives no output 1 of its shape"):
        check_model(broken.SerializeToString(), 7, 4, max_bytes=LIMIT)
