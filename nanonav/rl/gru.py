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
    reset, its gates ``r`` and ``z``, its new state ``n`` and ``h W_hh + b_hh``. Each step's
    tensors are taken as views once (``unbind``), not indexed anew at every step, and the
    backward's gate derivatives that need no carried gradient are made for every step at
    once before its loop: at 512 sequences of 25 units an operation costs what it costs to
    call, so the loops do as few as they can."""

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
        gh = x.new_empty(steps, sequences, 3 * units)  # h W_hh + b_hh
        out = x.new_empty(steps, sequences, units)
        w_hh_t = w_hh.t()
        step_views = zip(
            kept.unbind(0), memories.unbind(0), gh.unbind(0), gates.unbind(0),
            gi[..., : 2 * units].unbind(0), gi[..., 2 * units :].unbind(0),
            gh[..., : 2 * units].unbind(0), gh[..., 2 * units :].unbind(0),
            gates[..., :units].unbind(0), gates[..., units:].unbind(0), news.unbind(0),
            out.unbind(0), strict=True,
        )  # fmt: skip
        h = h0
        for kept_t, h_t, gh_t, gates_t, gi_rz, gi_n, gh_rz, gh_n, r, z, n, out_t in step_views:
            h = torch.mul(h, kept_t, out=h_t)
            torch.addmm(b_hh, h, w_hh_t, out=gh_t)
            torch.add(gi_rz, gh_rz, out=gates_t).sigmoid_()
            torch.addcmul(gi_n, r, gh_n, out=n).tanh_()
            h = torch.addcmul(n, z, h - n, out=out_t)
        ctx.save_for_backward(xs, kept, w_ih, w_hh, memories, gates, news, gh)
        return out.transpose(0, 1)

    @staticmethod
    def backward(ctx: Any, d_out: Tensor) -> tuple[Tensor | None, ...]:
        xs, kept, w_ih, w_hh, memories, gates, news, gh = ctx.saved_tensors
        steps, sequences, units = news.shape
        r, z = gates[..., :units], gates[..., units:]
        # the derivatives of the step's output by its gates' inputs, but for the gradient
        # that arrives at the step (which the loop multiplies in)
        by_n = (1.0 - z) * (1.0 - news * news)  # d h' / d (n's input)
        by_z = (memories - news) * z * (1.0 - z)  # d h' / d (z's input)
        by_r = gh[..., 2 * units :] * r * (1.0 - r)  # d (n's input) / d (r's input)
        # the gates' input gradients in one buffer laid out (n's input, r, z, h W_hn + b_hn):
        # the input side's (n, r, z) and the memory side's (r, z, hn) are each one slice of
        # it, so no copy joins them (the input weights' rows are taken n first to match)
        d_gates = d_out.new_empty(steps, sequences, 4 * units)
        d_steps = d_out.transpose(0, 1)
        step_views = zip(
            d_steps.unbind(0), by_n.unbind(0), by_z.unbind(0), by_r.unbind(0), r.unbind(0),
            z.unbind(0), kept.unbind(0), d_gates[..., :units].unbind(0),
            d_gates[..., units:].unbind(0), d_gates[..., units : 2 * units].unbind(0),
            d_gates[..., 2 * units : 3 * units].unbind(0), d_gates[..., 3 * units :].unbind(0),
            strict=True,
        )  # fmt: skip
        carry: Tensor | None = None
        for (
            d_t,
            by_n_t,
            by_z_t,
            by_r_t,
            r_t,
            z_t,
            kept_t,
            d_n_t,
            d_gh_t,
            d_r,
            d_z,
            d_hn,
        ) in reversed(list(step_views)):
            dh = d_t if carry is None else d_t + carry
            torch.mul(dh, by_n_t, out=d_n_t)
            torch.mul(dh, by_z_t, out=d_z)
            torch.mul(d_n_t, by_r_t, out=d_r)
            torch.mul(d_n_t, r_t, out=d_hn)
            carry = torch.addmm(dh * z_t, d_gh_t, w_hh).mul_(kept_t)
        flat = d_gates.view(steps * sequences, 4 * units)
        flat_gh, flat_gi = flat[:, units:], flat[:, : 3 * units]  # (r, z, hn) and (n, r, z)
        # the weights' gradients as (inputs x gates) products, transposed after: with
        # thousands of rows and a handful of columns MKL's product is 1.2-3x faster so
        d_w_hh = (memories.view(steps * sequences, units).t() @ flat_gh).t()
        d_b_hh = flat_gh.sum(0)
        n_first = (xs.t() @ flat_gi).t()
        d_w_ih = torch.cat([n_first[units:], n_first[:units]])
        n_first_b = flat_gi.sum(0)
        d_b_ih = torch.cat([n_first_b[units:], n_first_b[:units]])
        d_x = None
        if ctx.needs_input_grad[0]:
            w_ih_n_first = torch.cat([w_ih[2 * units :], w_ih[: 2 * units]])
            d_x = (flat_gi @ w_ih_n_first).view(steps, sequences, -1).transpose(0, 1)
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
