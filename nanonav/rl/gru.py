"""A GRU stepped through whole sequences with a backward of its own, for the recurrent update.

Why not ``nn.GRUCell`` in a loop: autograd then records each step's gates as a dozen nodes and
computes each step's weight gradients as small matrix products of their own, which was most of
a recurrent update's time on one core. Here the input's projection is one product before the
loop, a step is one product and the gates' arithmetic, and the weights' gradients are one
product each after the backward loop. ``nn.GRU`` cannot serve: a world's memory is zeroed where
its episode starts, which may be inside a sequence.

The arithmetic is PyTorch's GRU (``nn.GRUCell``'s weights, gates ordered reset, update, new)::

    r = sigmoid(x W_ir + b_ir + h W_hr + b_hr)
    z = sigmoid(x W_iz + b_iz + h W_hz + b_hz)
    n = tanh(x W_in + b_in + r * (h W_hn + b_hn))
    h' = (1 - z) * n + z * h
"""

from __future__ import annotations

from typing import Any

import torch
from torch import Tensor, nn


class _GRUSequence(torch.autograd.Function):
    """The forward keeps, time-major, what the backward needs: each step's memory after its
    reset, its reset and update gates, its new state ``n`` and ``h W_hn + b_hn``."""

    @staticmethod
    def forward(
        ctx: Any, x: Tensor, h0: Tensor, keep: Tensor, w_ih: Tensor, w_hh: Tensor,
        b_ih: Tensor, b_hh: Tensor,
    ) -> Tensor:  # fmt: skip
        sequences, steps, width = x.shape
        units = w_hh.shape[1]
        xs = x.transpose(0, 1).reshape(steps * sequences, width)
        gi = torch.addmm(b_ih, xs, w_ih.t()).view(steps, sequences, 3 * units)
        kept = keep.t().unsqueeze(-1).to(x.dtype)  # (steps, sequences, 1)
        memories = x.new_empty(steps, sequences, units)  # each step's memory, reset applied
        gates = x.new_empty(steps, sequences, 2 * units)  # r, z
        news = x.new_empty(steps, sequences, units)  # n
        hidden_new = x.new_empty(steps, sequences, units)  # h W_hn + b_hn
        out = x.new_empty(steps, sequences, units)
        w_hh_t = w_hh.t()
        h = h0
        for t in range(steps):
            h = torch.mul(h, kept[t], out=memories[t])
            gh = torch.addmm(b_hh, h, w_hh_t)
            torch.sigmoid(gi[t, :, : 2 * units] + gh[:, : 2 * units], out=gates[t])
            hidden_new[t] = gh[:, 2 * units :]
            n = torch.addcmul(gi[t, :, 2 * units :], gates[t, :, :units], hidden_new[t])
            torch.tanh(n, out=news[t])
            h = torch.addcmul(news[t], gates[t, :, units:], h - news[t], out=out[t])
        ctx.save_for_backward(xs, kept, w_ih, w_hh, memories, gates, news, hidden_new)
        return out.transpose(0, 1)

    @staticmethod
    def backward(ctx: Any, d_out: Tensor) -> tuple[Tensor | None, ...]:
        xs, kept, w_ih, w_hh, memories, gates, news, hidden_new = ctx.saved_tensors
        steps, sequences, units = news.shape
        d_steps = d_out.transpose(0, 1)
        d_gi = xs.new_empty(steps, sequences, 3 * units)  # the input projection's gradient
        d_hn = xs.new_empty(steps, sequences, units)  # (h W_hn + b_hn)'s
        w_hrz, w_hn = w_hh[: 2 * units], w_hh[2 * units :]
        carry = torch.zeros_like(news[0])
        for t in reversed(range(steps)):
            r, z = gates[t, :, :units], gates[t, :, units:]
            n, h = news[t], memories[t]
            dh = d_steps[t] + carry
            d_n = d_gi[t, :, 2 * units :]
            torch.mul(dh * (1.0 - z), 1.0 - n * n, out=d_n)
            torch.mul(dh * (h - n), z * (1.0 - z), out=d_gi[t, :, units : 2 * units])
            torch.mul(d_n * hidden_new[t], r * (1.0 - r), out=d_gi[t, :, :units])
            torch.mul(d_n, r, out=d_hn[t])
            d_h = torch.addmm(dh * z, d_gi[t, :, : 2 * units], w_hrz)
            d_h.addmm_(d_hn[t], w_hn)
            carry = d_h * kept[t]
        flat_gi = d_gi.view(steps * sequences, 3 * units)
        flat_rz = flat_gi[:, : 2 * units]
        flat_hn = d_hn.view(steps * sequences, units)
        flat_h = memories.view(steps * sequences, units)
        d_w_hh = torch.cat([flat_rz.t() @ flat_h, flat_hn.t() @ flat_h])
        d_b_hh = torch.cat([flat_rz.sum(0), flat_hn.sum(0)])
        d_w_ih = flat_gi.t() @ xs
        d_b_ih = flat_gi.sum(0)
        d_x = None
        if ctx.needs_input_grad[0]:
            d_x = (flat_gi @ w_ih).view(steps, sequences, -1).transpose(0, 1)
        d_h0 = carry if ctx.needs_input_grad[1] else None
        return d_x, d_h0, None, d_w_ih, d_w_hh, d_b_ih, d_b_hh


def gru_sequence(cell: nn.GRUCell, x: Tensor, memory: Tensor, starts: Tensor) -> Tensor:
    """``cell`` stepped through ``x`` shaped ``(sequences, steps, width)`` from ``memory``
    ``(sequences, units)``, the memory zeroed before each step where ``starts`` (``(sequences,
    steps)``, bool) says an episode started: the memory after each step, ``(sequences, steps,
    units)``, as the cell in a loop gives it, with gradients for the cell's weights, ``x`` and
    ``memory``."""
    keep = ~starts
    answer: Tensor = _GRUSequence.apply(  # type: ignore[no-untyped-call]
        x, memory, keep, cell.weight_ih, cell.weight_hh, cell.bias_ih, cell.bias_hh
    )
    return answer
