"""Depth-first tree decoder (paper §4.3, eq. 9–11, with per-node latents): teacher forcing
and batched greedy decoding.

The decoder walks a tree depth-first, like JT-VAE's DFS trace. Node ``i`` is read as its
one-hot type ``e_i``, ``x_i^p = W^p e_i``, and its own :class:`~robovae.model.tree.TreeGRUCell`
passes messages:

- up message (sent when the walk backtracks from ``c``):
  ``h_{c->p} = GRU(x_c^p, {h_{k->c}}_{k child of c})``;
- down message (sent when ``p`` expands into ``c``):
  ``h_{p->c} = GRU(x_p^p, {h_{parent(p)->p}} + {h_{k->p}}_{k earlier sibling of c})``.

Every node ``c`` carries a latent ``w_c`` (``node_latent_dim`` wide; its posterior comes from
:class:`~robovae.model.encoder.TreeEncoder`). A node with ``K`` children makes ``K + 1``
topology decisions: on arrival and after returning from each child; the first ``K`` are
"expand" (1), the last "backtrack" (0). With ``k`` the children made so far and ``d_i`` the
depth, a decision and a node's type read only the node's own latent and that context:

.. math::
    p_t = \\sigma(u \\cdot \\mathrm{ReLU}(W_4 w_i + b + E_{depth}(d_i) + E_{count}(k) + k\\,c)),
    \\qquad s_c = V^c w_c + b^c

(embeddings clamped at ``max_depth_embed`` / ``max_children_embed``; the linear ``k c`` lets
counts beyond the embedded ones extrapolate). Features (eq. 10, with a linear path from the
node latent, so a value outside the training range moves the output linearly):

.. math::
    a = \\mathrm{ReLU}(W_1^l z + W_2^l h_{p \\to c} + W_3^l w_c), \\qquad
    f_c = U^l a + V^l w_c

(the root has ``h = 0``). For generation the node latents have a learned conditional prior
(a sequential VAE's):

.. math:: p(w_c \\mid z, h_{p \\to c}, w_p) = \\mathcal N(\\mu^p, \\mathrm{diag}\\, e^{\\lambda^p}),
          \\quad [\\mu^p, \\lambda^p] = U^p \\mathrm{ReLU}(W_1^p z + W_2^p h_{p \\to c} + W_3^p w_p)

(``w_p = 0``, ``h = 0`` at the root; ``lambda^p`` soft-clamped to ``(-10, 10)``). The messages
read neither ``z`` nor ``w``, so the encoder's and the decoder's level passes run stacked.
Reconstruction feeds the encoder's ``w`` in pre-order; generation draws every new node's ``w``
from the prior (ancestral sampling with the caller's noise, or its mean without). Why each part
is there: ``docs/results.md`` (ablation).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import Tensor, nn
from torch_geometric.data import Data

from robovae.model.messages import level_messages
from robovae.model.tree import TreeGRUCell, TreeSchedule, soft_clamp, tree_schedule


@dataclass
class DecoderOutput:
    """Teacher-forcing predictions for a batch.

    Attributes:
        topo_logits: ``[T]`` expansion logits, one per decision, in DFS-trace order per graph
            (graphs in batch order), ``T = 2N - B``.
        topo_target: ``[T]`` float labels, 1 expand / 0 backtrack.
        topo_graph: ``[T]`` graph index of each decision; ``topo_node``: ``[T]`` deciding node.
        feat_pred: ``[N, d]`` predicted (normalised) features, batch node order.
        type_logits: ``[N, num_types]`` (zeros when ``num_types == 1``).
        prior_mu, prior_logvar: ``[N, node_latent_dim]`` the node latents' conditional prior
            (``None`` without node latents).
    """

    topo_logits: Tensor
    topo_target: Tensor
    topo_graph: Tensor
    topo_node: Tensor
    feat_pred: Tensor
    type_logits: Tensor
    prior_mu: Tensor | None = None
    prior_logvar: Tensor | None = None


class TopoHead(nn.Module):
    """Expansion logit of a decision from the deciding node's latent, its depth and its number
    of children so far (module docstring)."""

    def __init__(self, hidden_dim: int, node_latent_dim: int, max_depth_embed: int,
                 max_children_embed: int) -> None:
        super().__init__()
        self.W4 = nn.Linear(node_latent_dim, hidden_dim)
        self.u = nn.Linear(hidden_dim, 1)
        self.depth_emb = nn.Embedding(max_depth_embed + 1, hidden_dim)
        self.count_emb = nn.Embedding(max_children_embed + 1, hidden_dim)
        self.count_vec = nn.Parameter(torch.zeros(hidden_dim))

    def forward(self, w: Tensor, depth: Tensor, count: Tensor) -> Tensor:
        """Logits ``[M]`` of ``M`` decisions: deciding nodes' latents ``w`` ``[M, dw]``, depths
        and child counts so far ``[M]``."""
        a = self.W4(w)
        a = a + self.depth_emb(depth.clamp_max(self.depth_emb.num_embeddings - 1))
        a = a + self.count_emb(count.clamp_max(self.count_emb.num_embeddings - 1))
        a = a + count[:, None].to(a.dtype) * self.count_vec
        return self.u(torch.relu(a)).squeeze(-1)


def decision_index(sched: TreeSchedule) -> tuple[Tensor, Tensor, Tensor, Tensor, Tensor]:
    """The ``T = 2N - B`` topology decisions of a batch in DFS-trace order (cached on ``sched``).

    Returns ``(node, count, target, which, graph)``: deciding node, its number of children so
    far, label (1 expand / 0 backtrack), row of the decision's inward message sum in
    ``cat([sdown, total])`` (level order, :func:`~robovae.model.tree.level_messages`) and graph.
    """
    if "decisions" in sched.cache:
        return sched.cache["decisions"]
    parent = sched.parent
    n = sched.num_nodes
    idx = torch.arange(n, device=parent.device)
    child = idx[parent >= 0]
    # expand into each non-root c (made by parent(c)), backtrack from each node
    node = torch.cat([parent[child], idx])
    count = torch.cat([sched.rank[child], sched.num_children])
    target = torch.cat([torch.ones_like(child), torch.zeros_like(idx)]).float()
    # DFS-trace order: expand(c) at slot c; backtrack(i) right after i's subtree, deepest first
    dm = len(sched.sizes) - 1
    key_e = child * (dm + 2) + dm + 1
    key_b = (idx + sched.size) * (dm + 2) + dm - sched.depth
    order = torch.argsort(torch.cat([key_e, key_b]))
    node, count, target = node[order], count[order], target[order]
    which = torch.cat([sched.inv[child], sched.inv + n])[order]
    out = (node, count, target, which, sched.graph[node])
    sched.cache["decisions"] = out
    return out


class TreeDecoder(nn.Module):
    """Depth-first tree decoder (module docstring).

    Args:
        feat_dim: feature width ``d`` (normalised units).
        num_types: number of node types.
        hidden_dim: message / hidden width ``H``.
        latent_dim: width of ``z``.
        node_latent_dim: width of the node latents ``w`` (at least 1).
        type_mask: optional ``[num_types, d]`` bool (``FeatureSet.type_mask()``): decoded nodes
            get zeros outside their type's columns, as real inputs have. Default: every column
            belongs to every type.
        max_depth_embed: depths above this share the last depth embedding.
        max_children_embed: child counts above this share the last count embedding.

    Raises:
        ValueError: ``node_latent_dim < 1``.
    """

    def __init__(self, feat_dim: int, num_types: int, hidden_dim: int, latent_dim: int,
                 node_latent_dim: int, type_mask: Tensor | None = None,
                 max_depth_embed: int = 32, max_children_embed: int = 16) -> None:
        super().__init__()
        if node_latent_dim < 1:
            raise ValueError(f"the decoder needs node latents (node_latent_dim >= 1), "
                             f"got {node_latent_dim}")
        self.feat_dim, self.num_types, self.hidden_dim = feat_dim, num_types, hidden_dim
        self.node_latent_dim = node_latent_dim
        self.proj = nn.Linear(num_types, hidden_dim, bias=False)
        self.cell = TreeGRUCell(hidden_dim)
        self.topo = TopoHead(hidden_dim, node_latent_dim, max_depth_embed, max_children_embed)
        self.W1_l = nn.Linear(latent_dim, hidden_dim)
        self.W2_l = nn.Linear(hidden_dim, hidden_dim, bias=False)
        self.W3_l = nn.Linear(node_latent_dim, hidden_dim, bias=False)
        self.U_l = nn.Linear(hidden_dim, feat_dim)
        self.V_l = nn.Linear(node_latent_dim, feat_dim, bias=False)
        self.V_c = nn.Linear(node_latent_dim, num_types) if num_types > 1 else None
        self.W1_p = nn.Linear(latent_dim, hidden_dim)
        self.W2_p = nn.Linear(hidden_dim, hidden_dim, bias=False)
        self.W3_p = nn.Linear(node_latent_dim, hidden_dim, bias=False)
        self.U_p = nn.Linear(hidden_dim, 2 * node_latent_dim)
        mask = torch.ones(num_types, feat_dim, dtype=torch.bool) if type_mask is None else type_mask
        self.register_buffer("type_mask", mask.bool().clone(), persistent=False)

    def node_inputs(self, node_type: Tensor, dtype: torch.dtype) -> Tensor:
        """What the decoder reads of a node: its one-hot type ``[N, num_types]``."""
        return F.one_hot(node_type, self.num_types).to(dtype)

    def node_heads(self, zl: Tensor, h: Tensor, w: Tensor) -> tuple[Tensor, Tensor]:
        """``(features, type logits)`` of new nodes (module docstring) from ``zl = W_1^l z``,
        their parent's message ``h`` and their latents ``w``."""
        a = torch.relu(zl + self.W2_l(h) + self.W3_l(w))
        types = a.new_zeros(a.shape[0], 1) if self.V_c is None else self.V_c(w)
        return self.U_l(a) + self.V_l(w), types

    def node_prior(self, zp: Tensor, h: Tensor, w_parent: Tensor) -> tuple[Tensor, Tensor]:
        """``(mu^p, logvar^p)`` of the node latents' prior (module docstring) from
        ``zp = W_1^p z``, the parent's message ``h`` and the parent's latent."""
        a = torch.relu(zp + self.W2_p(h) + self.W3_p(w_parent))
        mu, logvar = self.U_p(a).chunk(2, -1)
        return mu, soft_clamp(logvar)

    # --- teacher forcing ----------------------------------------------------------------

    def teacher_forcing(self, z: Tensor, batch: Data, w: Tensor,
                        sched: TreeSchedule | None = None,
                        messages: tuple[Tensor, Tensor, Tensor] | None = None) -> DecoderOutput:
        """All predictions of the DFS trace of ``batch`` given ``z`` ``[B, latent_dim]`` and the
        node latents ``w`` ``[N, node_latent_dim]`` (node order).

        Messages are computed level by level (:func:`~robovae.model.messages.level_messages`),
        then every decision of the batch in one call of the topology head. ``messages``
        (``(down, total, sdown)`` of this decoder's cell, level order, ``[N, H]`` each) skips
        the message passes when they were already computed (together with the encoder's).
        """
        sched = tree_schedule(batch) if sched is None else sched
        if messages is None:
            px = self.project_levels(batch.node_type, sched, z.dtype)
            messages = tuple(t[0] for t in level_messages([self.cell], px[None], sched, 0))
        down, _, _ = messages
        node, count, target, _, graph = decision_index(sched)
        logits = self.topo(w.index_select(0, node), sched.depth.index_select(0, node), count)
        h = down.index_select(0, sched.inv)
        feat, types = self.node_heads(self.W1_l(z).index_select(0, sched.graph), h, w)
        w_par = torch.where((sched.parent >= 0)[:, None],
                            w.index_select(0, sched.parent.clamp_min(0)), 0.0)
        pmu, plogvar = self.node_prior(self.W1_p(z).index_select(0, sched.graph), h, w_par)
        return DecoderOutput(logits, target, graph, node, feat, types, pmu, plogvar)

    def project_levels(self, node_type: Tensor, sched: TreeSchedule,
                       dtype: torch.dtype) -> Tensor:
        """``cell.project(x^p)`` of the nodes' one-hot types, rows in level order, ``[N, 3H]``."""
        x = self.node_inputs(node_type.index_select(0, sched.order), dtype)
        return self.cell.project(x, self.proj.weight)

    forward = teacher_forcing

    # --- greedy decoding ----------------------------------------------------------------

    @torch.no_grad()
    def decode(self, z: Tensor, max_nodes: int = 256, max_depth: int = 64,
               node_latents: Sequence[Tensor] | None = None,
               node_noise: Tensor | None = None) -> list[tuple[Tensor, Tensor, Tensor]]:
        """Greedy autoregressive decoding of ``z`` ``[B, l]`` (or ``[l]``), batched over latents.

        Every active latent advances one DFS step per iteration (one GRU call for all): expand
        when ``p > 0.5`` (and the tree has fewer than ``max_nodes`` nodes and the child's depth
        would be at most ``max_depth``), else backtrack; a tree is finished when its root
        backtracks or it reaches ``max_nodes``. Each tree takes at most ``2 * max_nodes - 1``
        steps, so decoding always terminates. Node types are ``argmax`` of the type logits.

        The ``t``-th node created for latent ``b`` (pre-order) takes
        ``node_latents[b][t]`` when given (reconstruction: the encoder's node means), else a
        draw from its conditional prior, ``mu^p + sigma^p * node_noise[b, t]`` (ancestral
        sampling; ``node_noise`` is ``[B, >= max_nodes, node_latent_dim]``, already scaled by
        the sampling temperature), or the prior mean ``mu^p`` without ``node_noise``.

        Returns:
            per latent ``(parent, node_type, x)``: pre-order parent vector (root -1), types and
            normalised features ``[n, d]`` (zero outside the node type's columns).

        Raises:
            ValueError: when ``z`` holds NaN or infinite values. Huge finite values do not
                raise (features may then be non-finite; NaN logits mean "backtrack").
        """
        z = z[None] if z.dim() == 1 else z
        if not bool(torch.isfinite(z).all()):
            bad = (~torch.isfinite(z)).any(1).nonzero().flatten().tolist()
            raise ValueError(f"latents must be finite; rows {bad[:10]} contain NaN or inf")
        if max_nodes < 1 or max_depth < 0:
            raise ValueError("max_nodes must be >= 1 and max_depth >= 0")
        b, dev, hid = z.shape[0], z.device, self.hidden_dim
        buf = _NodeBuffer(b * min(max_nodes, 32), self.feat_dim, hid, self.node_latent_dim,
                          z.dtype, dev)
        zl = self.W1_l(z)
        lat = torch.arange(b, device=dev)
        wsrc = _NodeLatents(self, z, node_latents, node_noise, max_nodes)
        h0 = z.new_zeros(b, hid)
        w = wsrc.take(lat, torch.zeros_like(lat), h0, z.new_zeros(b, self.node_latent_dim))
        feat, types = self._new_nodes(zl, h0, w)
        cur = buf.add(lat, torch.full_like(lat, -1), torch.zeros_like(lat), types, feat,
                      self._px(types, z.dtype), h0, w)
        count = torch.ones_like(lat)
        active = count < max_nodes
        for _ in range(2 * max_nodes):
            act = active.nonzero().flatten()
            if act.numel() == 0:
                break
            i = cur[act]
            inward = buf.down[i] + buf.csum[i]
            logit = self.topo(buf.w[i], buf.depth[i], buf.nchild[i])
            expand = (logit > 0) & (buf.depth[i] < max_depth)
            pxi = buf.px[i]
            s = torch.where(expand[:, None], inward, buf.csum[i])
            g = buf.cgated[i] + torch.where(expand[:, None], self.cell.gate_p(pxi, buf.down[i]),
                                            0.0)
            h = self.cell.step(pxi, s, g)
            e, k = expand.nonzero().flatten(), (~expand).nonzero().flatten()
            if e.numel():  # expanders create a child and move into it
                be, pe, he = act[e], i[e], h[e]
                w = wsrc.take(be, count[be], he, buf.w[pe])
                feat, types = self._new_nodes(zl[be], he, w)
                px = self._px(types, z.dtype)
                cur[be] = buf.add(be, pe, buf.depth[pe] + 1, types, feat, px, he, w)
                buf.nchild[pe] += 1
                count[be] += 1
            if k.numel():  # backtrackers send their up message and move to their parent
                bk, ik = act[k], i[k]
                par = buf.parent[ik]
                root = par < 0
                active[bk[root]] = False
                up, pk = h[k][~root], par[~root]
                buf.csum.index_add_(0, pk, up)
                buf.cgated.index_add_(0, pk, self.cell.gate_p(buf.px[pk], up))
                cur[bk[~root]] = pk
            active &= count < max_nodes
        return buf.split(b)

    def _px(self, node_type: Tensor, dtype: torch.dtype) -> Tensor:
        return self.cell.project(self.proj(self.node_inputs(node_type, dtype)))

    def _new_nodes(self, zl: Tensor, h: Tensor, w: Tensor) -> tuple[Tensor, Tensor]:
        feat, logits = self.node_heads(zl, h, w)
        types = logits.argmax(-1)
        return torch.where(self.type_mask[types], feat, torch.zeros_like(feat)), types


class _NodeLatents:
    """Where greedy decoding takes each new node's latent ``w`` from: the given latents of the
    latent's robot while they last (pre-order index ``t``), else the conditional prior."""

    def __init__(self, dec: TreeDecoder, z: Tensor, given: Sequence[Tensor] | None,
                 noise: Tensor | None, max_nodes: int) -> None:
        self.dec, self.dim = dec, dec.node_latent_dim
        b = z.shape[0]
        if given is not None and len(given) != b:
            raise ValueError(f"node_latents: {len(given)} robots for {b} latents")
        if noise is not None and (noise.dim() != 3 or noise.shape[0] != b
                                  or noise.shape[1] < max_nodes or noise.shape[2] != self.dim):
            raise ValueError(f"node_noise must be [{b}, >= {max_nodes}, {self.dim}], "
                             f"got {list(noise.shape)}")
        self.noise = None if noise is None else noise.to(z)
        self.zp = dec.W1_p(z)
        given = list(given) if given is not None else []
        for k, g in enumerate(given):
            if g.dim() != 2 or g.shape[1] != self.dim:
                raise ValueError(f"node_latents[{k}] must be [n, {self.dim}], "
                                 f"got {list(g.shape)}")
        lens = [int(g.shape[0]) for g in given] or [0] * b
        self.lens = torch.tensor(lens, dtype=torch.long, device=z.device)
        self.table = z.new_zeros(b, max(lens, default=0), self.dim)
        for k, g in enumerate(given):
            self.table[k, :g.shape[0]] = g.to(z)

    def take(self, rows: Tensor, t: Tensor, h: Tensor, w_parent: Tensor) -> Tensor:
        """Latents of the new nodes number ``t`` of latents ``rows`` (parent message ``h``)."""
        have = t < self.lens[rows]
        if bool(have.all()):  # reconstruction: every node's latent is given, no prior needed
            return self.table[rows, t]
        mu, logvar = self.dec.node_prior(self.zp[rows], h, w_parent)
        w = mu
        if self.noise is not None:
            w = mu + torch.exp(0.5 * logvar) * self.noise[rows, t]
        if bool(have.any()):
            tt = t.clamp_max(max(self.table.shape[1] - 1, 0))
            w = torch.where(have[:, None], self.table[rows, tt], w)
        return w


class _NodeBuffer:
    """Growable flat storage of the nodes being decoded (all latents interleaved)."""

    def __init__(self, cap: int, d: int, hid: int, dw: int, dtype: torch.dtype,
                 dev: torch.device) -> None:
        self.n = 0
        long = {"dtype": torch.long, "device": dev}
        flt = {"dtype": dtype, "device": dev}
        self.owner, self.parent = torch.zeros(cap, **long), torch.zeros(cap, **long)
        self.depth, self.type = torch.zeros(cap, **long), torch.zeros(cap, **long)
        self.nchild = torch.zeros(cap, **long)
        self.x, self.w = torch.zeros(cap, d, **flt), torch.zeros(cap, dw, **flt)
        self.px, self.down = torch.zeros(cap, 3 * hid, **flt), torch.zeros(cap, hid, **flt)
        self.csum, self.cgated = torch.zeros(cap, hid, **flt), torch.zeros(cap, hid, **flt)

    _FIELDS = ("owner", "parent", "depth", "type", "nchild", "x", "w", "px", "down", "csum",
               "cgated")

    def add(self, owner: Tensor, parent: Tensor, depth: Tensor, types: Tensor, x: Tensor,
            px: Tensor, down: Tensor, w: Tensor) -> Tensor:
        """Append nodes (children's ``nchild``/``csum``/``cgated`` start at zero); their ids."""
        m = owner.numel()
        if self.n + m > self.owner.shape[0]:
            cap = max(2 * self.owner.shape[0], self.n + m)
            for f in self._FIELDS:
                old = getattr(self, f)
                new = old.new_zeros((cap, *old.shape[1:]))
                new[: self.n] = old[: self.n]
                setattr(self, f, new)
        ids = torch.arange(self.n, self.n + m, device=owner.device)
        self.owner[ids], self.parent[ids], self.depth[ids], self.type[ids] = (
            owner, parent, depth, types)
        self.x[ids], self.px[ids], self.down[ids], self.w[ids] = x, px, down, w
        self.n += m
        return ids

    def split(self, b: int) -> list[tuple[Tensor, Tensor, Tensor]]:
        """Per latent ``(parent, type, x)`` in creation order (= pre-order), local indices."""
        n = self.n
        owner = self.owner[:n]
        order = torch.argsort(owner, stable=True)
        counts = torch.bincount(owner, minlength=b)
        start = torch.cumsum(counts, 0) - counts
        local = torch.empty_like(owner)
        local[order] = torch.arange(n, device=owner.device) - start[owner[order]]
        par = self.parent[:n]
        par = torch.where(par >= 0, local[par.clamp_min(0)], par)
        parts = zip(torch.split(par[order], counts.tolist()),
                    torch.split(self.type[:n][order], counts.tolist()),
                    torch.split(self.x[:n][order], counts.tolist()))
        return [(p.clone(), t.clone(), x.clone()) for p, t, x in parts]
