"""The recurrent update's GRU (nanonav.rl.gru) against the cell it stands in for."""

from __future__ import annotations

import torch
from torch import Tensor, nn

from nanonav.rl.gru import gru_sequence


def _cell_loop(cell: nn.GRUCell, x: Tensor, memory: Tensor, starts: Tensor) -> Tensor:
    outputs, h = [], memory
    for t in range(x.shape[1]):
        h = cell(x[:, t], h * (~starts[:, t]).unsqueeze(-1).to(x.dtype))
        outputs.append(h)
    return torch.stack(outputs, dim=1)


def _case(dtype: torch.dtype) -> tuple[nn.GRUCell, Tensor, Tensor, Tensor]:
    generator = torch.Generator().manual_seed(7)
    cell = nn.GRUCell(3, 5).to(dtype)
    x = torch.randn(6, 9, 3, generator=generator, dtype=dtype, requires_grad=True)
    memory = torch.randn(6, 5, generator=generator, dtype=dtype, requires_grad=True)
    starts = torch.rand(6, 9, generator=generator) < 0.2  # episodes start inside sequences
    starts[0, 4] = True
    return cell, x, memory, starts


def test_the_sequence_and_every_gradient_are_the_cell_loops() -> None:
    cell, x, memory, starts = _case(torch.float64)
    weights = (torch.randn(6, 9, 5, dtype=torch.float64),)  # an arbitrary loss's gradient
    answers: list[tuple[Tensor, Tensor, Tensor, list[Tensor]]] = []
    for run in (gru_sequence, _cell_loop):
        cell.zero_grad()
        x.grad = memory.grad = None
        out = run(cell, x, memory, starts)
        torch.autograd.backward((out * weights[0]).sum())
        grads = [p.grad.clone() for p in cell.parameters() if p.grad is not None]
        assert x.grad is not None and memory.grad is not None
        answers.append((out.detach(), x.grad.clone(), memory.grad.clone(), grads))
    (ours, x_ours, m_ours, g_ours), (loop, x_loop, m_loop, g_loop) = answers
    torch.testing.assert_close(ours, loop, rtol=1e-12, atol=1e-12)
    torch.testing.assert_close(x_ours, x_loop, rtol=1e-10, atol=1e-12)
    torch.testing.assert_close(m_ours, m_loop, rtol=1e-10, atol=1e-12)
    assert len(g_ours) == len(g_loop) == 4
    for mine, theirs in zip(g_ours, g_loop, strict=True):
        torch.testing.assert_close(mine, theirs, rtol=1e-10, atol=1e-12)


def test_its_backward_passes_torchs_numerical_gradient_check() -> None:
    cell, x, memory, starts = _case(torch.float64)
    # the input's and the memory's gradients numerically (the weights' against the loop above)
    assert torch.autograd.gradcheck(
        lambda x, m: gru_sequence(cell, x, m, starts), (x, memory), eps=1e-6, atol=1e-8
    )


def test_a_memory_zeroed_at_a_start_forgets_what_came_before() -> None:
    cell, x, memory, starts = _case(torch.float32)
    starts[:] = False
    starts[:, 3] = True
    with torch.no_grad():
        once = gru_sequence(cell, x, memory, starts)
        other = gru_sequence(cell, x, memory * 0 + 3.0, starts)
    assert not torch.allclose(once[:, 2], other[:, 2])
    torch.testing.assert_close(once[:, 3:], other[:, 3:])
