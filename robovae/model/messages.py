"""Level-scheduled message passes of the encoder and the decoder over a
:class:`~robovae.model.tree.TreeSchedule` (upward from the deepest level, then downward).

Speed (CPU): a training step is dominated by the sequential level loop (tens of levels, each a
few dozen small ops), so :func:`level_messages` runs the upward and downward passes of one or
several cells (the encoder's and the decoder's, stacked on a leading dimension and multiplied
with ``bmm``) as one autograd node with a hand-written backward: no per-op autograd bookkeeping,
no full-size zero gradients for per-level slices (indexing per-level rows out of ``[N, H]``
tensors under autograd fills a full-size zero gradient at every level), and the weight gradients
are computed once from all levels at the end. :func:`level_messages_reference` is the same
computation in plain autograd ops (tests compare values and gradients in float64).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import torch
from torch import Tensor

from robovae.model.tree import TreeGRUCell, TreeSchedule, exclusive_sibling_prefix

# --- level-scheduled message passes ----------------------------------------------------------
#
# Shapes: ``C`` stacked cells, rows in level order, ``px`` = ``[C, N, 3H]`` = ``[pz | ph | pr]``.
# Per level L (``n_L`` rows), ``at = sched.at[L]`` (the parents' positions in level L-1), a
# parent's quantities gathered per node are written ``q[par]``:
#
#   upward, L = D..0:   UG[L+1] = [up | r * up],  r = sigma(pr[par] + b_r + up U_r^T)
#                       SG[L]   = scatter_add(at, UG[L+1])        ([S | G]: child sums)
#                       up[L]   = step(pz[L], ph[L], SG[L])        (L >= 1)
#   downward, L = 1..D: XY[L-1] = [dn | r * dn] of level L-1       (+ SG[L-1] for encoders)
#                       sg      = XY[L-1][at] - UG[L]              (encoder: all but the node)
#                               = XY[L-1][at] + sibling_prefix(UG[L])   (decoder: earlier sibs)
#                       dn[L]   = step(pz[par], ph[par], sg)
#   step(pz, ph, [s | g]) = s + z (tanh(ph + g W_h^T) - s),  z = sigma(pz + s W_z^T)
#
# Outputs (level order, ``[C, N, H]``): ``down`` (message from the parent, 0 at the roots),
# ``total = down + S`` (everything a node receives) and ``sdown`` (the ``s`` of the down message:
# what the parent had received before expanding into the node; 0 at the roots).


def _sibling_prefix(v: Tensor, sched: TreeSchedule, lv: int) -> Tensor:
    """``[C, n, X]`` → for each node of level ``lv``, the sum over its earlier siblings
    (exact: a dense sibling table cumulated along the siblings, no subtraction)."""
    c, _, x = v.shape
    g, w = sched.num_groups[lv], sched.max_rank[lv] + 2
    dense = v.new_zeros(c, g * w, x).index_copy_(1, sched.prefix_dst[lv], v)
    dense = dense.view(c, g, w, x).cumsum(2).view(c, g * w, x)
    return dense.index_select(1, sched.prefix_src[lv])


def _sibling_suffix(v: Tensor, sched: TreeSchedule, lv: int) -> Tensor:
    """Adjoint of :func:`_sibling_prefix`: for each node, the sum over its later siblings."""
    c, _, x = v.shape
    g, w = sched.num_groups[lv], sched.max_rank[lv] + 2
    dense = v.new_zeros(c, g * w, x).index_copy_(1, sched.prefix_src[lv], v)
    dense = dense.view(c, g, w, x).flip(2).cumsum(2).flip(2).reshape(c, g * w, x)
    return dense.index_select(1, sched.prefix_dst[lv])


def _step_fwd(pz: Tensor, ph2: Tensor, s: Tensor, g: Tensor, wz: Tensor, wh2: Tensor,
              out: Tensor) -> tuple[Tensor, Tensor]:
    """``m = s + z (c - s)`` into ``out``; returns ``(z, c)``. ``z = sigma(pz + s W_z^T)``,
    ``c = tanh(ph + g W_h^T)`` computed as ``2 sigma(2 ph + g (2 W_h)^T) - 1`` (``ph2 = 2 ph``
    and ``wh2 = 2 W_h^T`` are given doubled: exact, and ``torch.tanh`` is ~5x slower on CPU)."""
    z = torch.baddbmm(pz, s, wz).sigmoid_()
    c = torch.baddbmm(ph2, g, wh2).sigmoid_().mul_(2.0).sub_(1.0)
    torch.lerp(s, c, z, out=out)
    return z, c


def _step_bwd(gm: Tensor, z: Tensor, c: Tensor, s: Tensor, wz_t: Tensor, wh_t: Tensor,
              da: Tensor, db: Tensor, gs: Tensor | None = None) -> tuple[Tensor, Tensor]:
    """Gradients of :func:`_step_fwd` from the output's ``gm`` (``gs``: an extra gradient on
    ``s``): those of ``pz``/``ph`` go into ``da``/``db``, those of ``(s, g)`` are returned;
    ``wz_t``/``wh_t`` are the transposed weights (``W_z``, ``W_h``, not doubled)."""
    torch.mul(gm * (c - s), torch.addcmul(z, z, z, value=-1.0), out=da)
    dc = gm * z
    torch.addcmul(dc, dc * c, c, value=-1.0, out=db)
    base = gm - dc
    if gs is not None:
        base += gs
    return torch.baddbmm(base, da, wz_t), torch.bmm(db, wh_t)


def _gate_bwd(gy: Tensor, m: Tensor, r: Tensor, ur_t: Tensor, out: Tensor) -> Tensor:
    """Gradients of ``y = r * m``, ``r = sigma(q)``, ``q = p + m U^T``: that of ``q`` into
    ``out``, that of ``m`` returned."""
    torch.mul(gy * m, torch.addcmul(r, r, r, value=-1.0), out=out)
    return torch.baddbmm(gy * r, out, ur_t)


def _levels(t: Tensor, sizes: list[int]) -> tuple[Tensor, ...]:
    """Per-level row views of ``[C, N, *]`` (one call, instead of one slice per level)."""
    return t.split(sizes, 1)


class _LevelMessages(torch.autograd.Function):
    """The upward and downward passes of ``C`` stacked cells (the comment block above).

    CPU-oriented layout: everything that depends only on a node's parent's features (its
    ``[pz | 2 ph | pr + b_r]``) is gathered once for all nodes (``pxp``), and the gradients
    that flow back to the parents are scattered once at the end; per-level results are written
    (``out=``) into full-size ``[C, N, *]`` buffers (no concatenation); the only per-level
    gathers read small contiguous blocks (``xy[L]`` = what a node's children add to their
    ``[s | g]``): indexing strided views is several times slower, worst with 2+ threads. The
    weight gradients are computed once, from all levels. Per-level views are made with one
    ``split`` per buffer: Python-level slicing is a visible cost at this op size.
    """

    # ctx: Any, as in torch.autograd.Function: it carries attributes of ours (sched, ne, fwd)
    # that torch's FunctionCtx does not declare
    @staticmethod
    def forward(ctx: Any, px: Tensor, wz: Tensor, wh: Tensor, ur: Tensor, br: Tensor,
                sched: TreeSchedule, num_encoder: int) -> tuple[Tensor, Tensor, Tensor]:
        c_, n, h = px.shape[0], px.shape[1], wz.shape[-1]
        sizes, at, max_rank = sched.sizes, sched.at, sched.max_rank
        depth, ne, n0 = len(sizes) - 1, num_encoder, sizes[0]
        dec = slice(ne, c_)
        mixed = 0 < ne < c_
        e = px.new_tensor([1.0] * ne + [0.0] * (c_ - ne))[:, None, None]  # encoder cells
        wh2 = wh * 2.0
        scale = px.new_tensor([1.0, 2.0, 1.0]).repeat_interleave(h)
        pxs = torch.addcmul(torch.cat([px.new_zeros(c_, 1, 2 * h), br], -1), px, scale)
        pxp = pxs.index_select(1, sched.parent_row)  # the parent's, per node (roots: junk)
        pz_p, ph_p, pr_p = (_levels(pxp[..., k * h:(k + 1) * h], sizes) for k in range(3))
        pz, ph, pr = (_levels(pxs[..., k * h:(k + 1) * h], sizes) for k in range(3))
        # inp = [[S | G] (upward) ; [s | g] (downward)], for the weight gradients; ug = [up | gu]
        inp = px.new_empty(c_, 2 * n, 2 * h)
        inp[:, :n + n0] = 0.0  # the upward sums (scatter targets) and the roots' [s | g]
        ug, down = px.new_empty(c_, n, 2 * h), px.new_empty(c_, n, h)
        ug[:, :n0] = 0.0
        down[:, :n0] = 0.0
        sgu, sgd = _levels(inp[:, :n], sizes), _levels(inp[:, n:], sizes)
        sgu_s, sgu_g = _levels(inp[:, :n, :h], sizes), _levels(inp[:, :n, h:], sizes)
        ugl, ug_m, ug_g = _levels(ug, sizes), _levels(ug[..., :h], sizes), \
            _levels(ug[..., h:], sizes)
        dnl = _levels(down, sizes)
        none: list = [None] * (depth + 1)
        r_up, zc_up, zc_dn, r_dn = list(none), list(none), list(none), list(none)
        for lv in range(depth, -1, -1):  # upward
            if lv < depth:
                m = ug_m[lv + 1]
                r = torch.baddbmm(pr_p[lv + 1], m, ur).sigmoid_()
                torch.mul(r, m, out=ug_g[lv + 1])
                r_up[lv + 1] = r
                sgu[lv].index_add_(1, at[lv + 1], ugl[lv + 1])
            if lv >= 1 and lv == depth:  # leaves only: s = g = 0, m = z * tanh(ph)
                z, c = pz[lv].sigmoid(), ph[lv].sigmoid().mul_(2.0).sub_(1.0)
                torch.mul(z, c, out=ug_m[lv])
                zc_up[lv] = (z, c)
            elif lv >= 1:
                zc_up[lv] = _step_fwd(pz[lv], ph[lv], sgu_s[lv], sgu_g[lv], wz, wh2, ug_m[lv])
        # xy[L]: [X | Y] of the nodes of level L, X = down (+ S), Y = r * down (+ G)
        xy = sgu[0] * e if ne else px.new_zeros(c_, n0, 2 * h)
        for lv in range(1, depth + 1):  # downward
            sg = xy.index_select(1, at[lv])
            if mixed:
                sg.addcmul_(ugl[lv], e, value=-1.0)
            elif ne:
                sg -= ugl[lv]
            if ne < c_ and max_rank[lv] > 0:
                sg[dec] += _sibling_prefix(ugl[lv][dec], sched, lv)
            m = dnl[lv]
            zc_dn[lv] = _step_fwd(pz_p[lv], ph_p[lv], sg[..., :h], sg[..., h:], wz, wh2, m)
            sgd[lv].copy_(sg)
            if lv < depth:
                r = torch.baddbmm(pr[lv], m, ur).sigmoid_()
                r_dn[lv] = xy_r = r
                xy = px.new_empty(c_, sizes[lv], 2 * h)
                if mixed:  # e = 1 for the encoder cells, 0 for the decoder's
                    torch.addcmul(m, e, sgu_s[lv], out=xy[..., :h])
                    torch.addcmul(sgu_g[lv] * e, xy_r, m, out=xy[..., h:])
                elif ne:
                    torch.add(m, sgu_s[lv], out=xy[..., :h])
                    torch.addcmul(sgu_g[lv], xy_r, m, out=xy[..., h:])
                else:
                    xy[..., :h] = m
                    torch.mul(xy_r, m, out=xy[..., h:])
        ctx.sched, ctx.ne = sched, num_encoder
        # ``down`` is also an output, whose ``grad_fn`` is this ``ctx``: keeping the output
        # object itself on ``ctx`` would make a reference cycle that only the cyclic garbage
        # collector frees (megabytes per training step piled up between its rare full passes)
        ctx.fwd = (inp, ug, down.detach(), r_up, zc_up, zc_dn, r_dn)
        ctx.save_for_backward(wz, wh, ur)
        return down, down + inp[:, :n, :h], inp[:, n:, :h]

    @staticmethod
    def backward(ctx: Any, g_down: Tensor, g_total: Tensor, g_sdown: Tensor
                 ) -> tuple[Tensor, Tensor, Tensor, Tensor, Tensor, None, None]:
        wz, wh, ur = ctx.saved_tensors
        sched, ne = ctx.sched, ctx.ne
        inp, ug, down, r_up, zc_up, zc_dn, r_dn = ctx.fwd
        c_, n, h = wz.shape[0], down.shape[1], wz.shape[-1]
        sizes, at, max_rank = sched.sizes, sched.at, sched.max_rank
        depth, n0 = len(sizes) - 1, sizes[0]
        dec, mixed = slice(ne, c_), 0 < ne < c_
        e = wz.new_tensor([1.0] * ne + [0.0] * (c_ - ne))[:, None, None]  # encoder cells
        wz_t, wh_t, ur_t = wz.transpose(1, 2), wh.transpose(1, 2), ur.transpose(1, 2)
        new = g_total.new_zeros
        gdn = g_down + g_total  # of down (a fresh tensor, accumulated in place)
        gug = new(c_, n, 2 * h)  # of [up | gu]
        gsg = []  # of [S | G], contiguous per level (gathered from)
        for t in _levels(g_total, sizes):
            gsg.append(new(c_, t.shape[1], 2 * h))
            gsg[-1][..., :h] = t
        # of the steps' [pz | ph]: [upward (own rows) ; downward (the parent's, per node)]
        act = g_total.new_empty(c_, 2 * n, 2 * h)
        act[:, :n0] = 0.0
        act[:, n:n + n0] = 0.0
        # of the gates' pre-activations: upward (the parent's pr, per node), downward (own pr)
        gq_up, gq_dn = new(c_, n, h), new(c_, n, h)
        gdnl, gugl = _levels(gdn, sizes), _levels(gug, sizes)
        gug_m, gug_g = _levels(gug[..., :h], sizes), _levels(gug[..., h:], sizes)
        au_a, au_b = _levels(act[:, :n, :h], sizes), _levels(act[:, :n, h:], sizes)
        ad_a, ad_b = _levels(act[:, n:, :h], sizes), _levels(act[:, n:, h:], sizes)
        sgu_s, sgd_s = _levels(inp[:, :n, :h], sizes), _levels(inp[:, n:, :h], sizes)
        gqu, gqd = _levels(gq_up, sizes), _levels(gq_dn, sizes)
        gsd, dnl, ug_m = _levels(g_sdown, sizes), _levels(down, sizes), \
            _levels(ug[..., :h], sizes)
        for lv in range(depth, 0, -1):  # downward pass, backwards
            p = lv - 1
            z, c = zc_dn[lv]
            ds, dg = _step_bwd(gdnl[lv], z, c, sgd_s[lv], wz_t, wh_t, ad_a[lv], ad_b[lv],
                               gsd[lv])
            dsg = torch.cat([ds, dg], -1)
            gxy = new(c_, sizes[p], 2 * h).index_add_(1, at[lv], dsg)  # of level p's [X | Y]
            if mixed:
                gugl[lv].addcmul_(dsg, e, value=-1.0)
                gsg[p].addcmul_(gxy, e)
            elif ne:
                gugl[lv].sub_(dsg)
                gsg[p] += gxy
            if ne < c_ and max_rank[lv] > 0:
                gugl[lv][dec] += _sibling_suffix(dsg[dec], sched, lv)
            if p >= 1:
                gm = gdnl[p]
                gm += gxy[..., :h]
                gm += _gate_bwd(gxy[..., h:], dnl[p], r_dn[p], ur_t, gqd[p])
        for lv in range(depth + 1):  # upward pass, backwards
            if lv >= 1 and lv == depth:  # the deepest level's [S | G]: 0, not used further
                z, c = zc_up[lv]
                gm = gug_m[lv]
                torch.mul(gm * c, torch.addcmul(z, z, z, value=-1.0), out=au_a[lv])
                dc = gm * z
                torch.addcmul(dc, dc * c, c, value=-1.0, out=au_b[lv])
            elif lv >= 1:
                z, c = zc_up[lv]
                ds, dg = _step_bwd(gug_m[lv], z, c, sgu_s[lv], wz_t, wh_t, au_a[lv], au_b[lv])
                gs = gsg[lv]
                gs[..., :h] += ds
                gs[..., h:] += dg
            if lv < depth:
                gu = gugl[lv + 1]
                gu += gsg[lv].index_select(1, at[lv + 1])
                gum = gug_m[lv + 1]
                gum += _gate_bwd(gug_g[lv + 1], ug_m[lv + 1], r_up[lv + 1], ur_t, gqu[lv + 1])
        gpx = torch.cat([act[:, :n], gq_dn], -1)  # own rows
        par = sched.parent_row[n0:]  # scatter the parents' gradients (non-roots)
        gpx[:, :, :2 * h].index_add_(1, par, act[:, n + n0:])
        gpx[:, :, 2 * h:].index_add_(1, par, gq_up[:, n0:])
        gwz = torch.bmm(inp[..., :h].transpose(1, 2), act[..., :h])
        gwh = torch.bmm(inp[..., h:].transpose(1, 2), act[..., h:])
        gur = torch.bmm(ug[..., :h].transpose(1, 2), gq_up).baddbmm_(down.transpose(1, 2), gq_dn)
        return gpx, gwz, gwh, gur, gpx[..., 2 * h:].sum(1, keepdim=True), None, None


def _stacked_weights(cells: Sequence[TreeGRUCell]) -> tuple[Tensor, Tensor, Tensor, Tensor]:
    """``(W_z^s^T, W_h^g^T, U_r^T, b_r)`` of the cells, stacked: ``[C, H, H]`` x3, ``[C, 1, H]``."""
    h = cells[0].hidden_dim
    wz = torch.stack([cell.W_z.weight[:, h:].t() for cell in cells])
    wh = torch.stack([cell.W_h.weight[:, h:].t() for cell in cells])
    ur = torch.stack([cell.U_r.weight.t() for cell in cells])
    br = torch.stack([cell.U_r.bias for cell in cells])[:, None]
    return wz, wh, ur, br


def level_messages(cells: Sequence[TreeGRUCell], px: Tensor, sched: TreeSchedule,
                   num_encoder: int) -> tuple[Tensor, Tensor, Tensor]:
    """Upward then downward messages of ``C`` cells over the same schedule, in level order.

    Args:
        cells: the ``C`` cells; the first ``num_encoder`` use the encoder's downward message
            (everything the parent received except from the node itself), the others the
            decoder's (what the parent had received before expanding into the node: its own
            parent's message and the up messages of the node's *earlier* siblings).
        px: ``[C, N, 3H]`` ``cell.project`` of each cell's ``x^p``, rows in level order.
        sched: the batch's :class:`TreeSchedule`.

    Returns:
        ``(down, total, sdown)``, ``[C, N, H]`` each, level order: the message from the parent
        (0 at roots), ``down`` + the sum of the children's up messages, and the sum ``s`` of
        the messages the parent had when sending ``down`` (0 at roots).
    """
    return _LevelMessages.apply(px, *_stacked_weights(cells), sched, num_encoder)


def level_messages_reference(cells: Sequence[TreeGRUCell], px: Tensor, sched: TreeSchedule,
                             num_encoder: int) -> tuple[Tensor, Tensor, Tensor]:
    """:func:`level_messages` written with the cells' own autograd ops, one cell at a time
    (for tests: same values, same gradients)."""
    sizes, at = sched.sizes, sched.at
    depth = len(sizes) - 1

    def rows(t: Tensor, lv: int) -> Tensor:
        return t[sched.offsets[lv]:sched.offsets[lv] + sizes[lv]]

    outs = []
    for ci, cell in enumerate(cells):
        pxc, h = px[ci], cell.hidden_dim
        # per level: up messages and their gated form (levels >= 1), the children's sums
        up: dict[int, Tensor] = {}
        gu: dict[int, Tensor] = {}
        s_up: dict[int, Tensor] = {}
        g_up: dict[int, Tensor] = {}
        for lv in range(depth, -1, -1):
            s = g = pxc.new_zeros(sizes[lv], h)
            if lv < depth:
                gu[lv + 1] = cell.gate_p(rows(pxc, lv)[at[lv + 1]], up[lv + 1])
                s = s.index_add(0, at[lv + 1], up[lv + 1])
                g = g.index_add(0, at[lv + 1], gu[lv + 1])
            s_up[lv], g_up[lv] = s, g
            if lv >= 1:
                up[lv] = cell.step(rows(pxc, lv), s, g)
        down, sdown = [pxc.new_zeros(sizes[0], h)], [pxc.new_zeros(sizes[0], h)]
        for lv in range(1, depth + 1):
            a = at[lv]
            pxp, dp = rows(pxc, lv - 1)[a], down[lv - 1][a]
            if ci < num_encoder:
                s = dp + s_up[lv - 1][a] - up[lv]
                g = cell.gate_p(pxp, dp) + g_up[lv - 1][a] - gu[lv]
            else:
                pre = exclusive_sibling_prefix(torch.cat([up[lv], gu[lv]], -1), sched.groups[lv],
                                               sched.rank[sched.levels[lv]],
                                               sched.num_groups[lv], sched.max_rank[lv])
                s = dp + pre[:, :h]
                g = cell.gate_p(pxp, dp) + pre[:, h:]
            sdown.append(s)
            down.append(cell.step(pxp, s, g))
        d = torch.cat(down)
        outs.append((d, d + torch.cat([s_up[lv] for lv in range(depth + 1)]), torch.cat(sdown)))
    down_all, total_all, sdown_all = (torch.stack(t) for t in zip(*outs))
    return down_all, total_all, sdown_all
