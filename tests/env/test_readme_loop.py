"""The README's training loop through the env runs as written, against a real API, and the table
it sends comes back as it learned it."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from tests.conftest import Api

README = Path(__file__).resolve().parents[2] / "README.md"


def _training_loop() -> str:
    text = README.read_text()
    start = text.index("A training loop through the env")
    block = text.index("```python\n", start) + len("```python\n")
    return text[block : text.index("```", block)]


def test_the_readmes_training_loop_learns_through_the_env_and_sends_its_table(api: Api) -> None:
    code = _training_loop().replace("http://127.0.0.1:8000", api.url)
    assert "range(200)" in code
    namespace: dict[str, Any] = {}
    exec(compile(code.replace("range(200)", "range(30)"), str(README), "exec"), namespace)
    q = namespace["q"]
    assert np.abs(q).sum() > 0, "the loop learned nothing"
    sent = api.client.get(f"/policies/{namespace['policy'].id}").json()
    assert sent["states"] == namespace["env"].state_labels
    np.testing.assert_array_equal(np.asarray(sent["values"]), q)
    assert namespace["policy"].policy_from == f"policy-{namespace['policy'].id}"
