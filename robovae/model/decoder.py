"""Depth-first tree decoder (paper §4.3, eq. 9–11): teacher forcing and batched greedy decoding.

The decoder walks a tree depth-first, like JT-VAE's DFS trace. With ``x^p = W^p x`` (own weights)
and its own :class:`~robovae.model.tree.TreeGRUCell`:

- up message (sent when the walk backtracks from ``c``):
  ``h_{c->p} = GRU(x_c^p, {h_{k->c}}_{k child of c})``;
- down message (sent when ``p`` expands into ``c``):
  ``h_{p->c} = GRU(x_p^p, {h_{parent(p)->p}} + {h_{k->p}}_{k earlier sibling of c})``.

A node with ``K`` children makes ``K + 1`` topology decisions (eq. 9): on arrival and after
returning from each child; the first ``K`` are "expand" (1), the last "backtrack" (0):

.. math:: p_t = \\sigma(u^c \\cdot \\tau(W_1^c x_i + W_2^c z + W_3^c \\sum_k h_{k,i}
          [+ E_{depth}(d_i) + E_{count}(n_i)]))

where the sum runs over the messages received so far. The bracket (``topo_context=True``) adds
embeddings of the node's depth and of its number of children generated so far (both clamped): the
paper's §5 failure mode ("a node on the root always expands into a full limb") is a topology
head that cannot tell where it is; ``topo_context=False`` is exactly eq. 9.

**Decoder inputs** (``inputs``): with ``"features"`` (the paper), ``x_i`` above and the GRU inputs
``x^p`` are the node features: the true ones under teacher forcing, the decoder's own predictions
when decoding, so a feature error can flip a later topology decision (exposure bias), and an
unseen robot's unfamiliar feature values reach every decision. With ``"types"``, ``x_i`` is the
one-hot node type: the messages then carry the tree built so far (types, depths, sibling order)
and ``z`` alone carries the robot; teacher forcing and decoding see identical inputs whenever the
types are right. Features are predicted the same way (eq. 10) in both modes.

**Latent inputs** (``latent_inputs=True``, beyond the paper): in eq. 9–11 ``z`` reaches only the
heads, so the messages describe the tree built so far without knowing which robot is being built,
and a one-hidden-layer head must look the next decision up from ``(z, messages)``. With latent
inputs, every node's GRU input becomes ``x_i^p = W^p x_i + W^{zx} z`` (like the latent fed to
every step of an RNN decoder): the messages themselves are conditioned on the robot.

Each generated node ``c`` gets (eq. 10–11) ``a = ReLU(W_1^l z + W_2^l h_{p->c})``,
features ``f_c = U^l a`` and type logits ``U^c a`` (a categorical head over ``num_types``; absent
when there is a single type). The **root** has no parent message: it is predicted from ``z``
alone (``h = 0``).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import Tensor, nn
from torch_geometric.data import Data

from robovae.model.tree import TreeGRUCell, TreeSchedule, level_messages, tree_schedule

#: what the decoder reads of each node (:class:`TreeDecoder` ``inputs``)
INPUT_MODES = ("features", "types")


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
    """

    topo_logits: Tensor
    topo_target: Tensor
    topo_graph: Tensor
    topo_node: Tensor
    feat_pred: Tensor
    type_logits: Tensor


class TopoHead(nn.Module):
    """Expansion logit (eq. 9), optionally with depth / child-count context."""

    def __init__(self, feat_dim: int, hidden_dim: int, latent_dim: int, context: bool,
                 max_depth_embed: int, max_children_embed: int) -> None:
        super().__init__()
        self.W1 = nn.Linear(feat_dim, hidden_dim)
        self.W2 = nn.Linear(latent_dim, hidden_dim, bias=False)
        self.W3 = nn.Linear(hidden_dim, hidden_dim, bias=False)
        self.u = nn.Linear(hidden_dim, 1)
        self.context = context
        if context:
            self.depth_emb = nn.Embedding(max_depth_embed + 1, hidden_dim)
            self.count_emb = nn.Embedding(max_children_embed + 1, hidden_dim)

    def forward(self, x: Tensor, zw: Tensor, inward: Tensor, depth: Tensor,
                count: Tensor) -> Tensor:
        """Logits ``[M]``; ``zw`` is ``W2 z`` already gathered per decision."""
        a = self.W1(x) + zw + self.W3(inward)
        if self.context:
            a = a + self.depth_emb(depth.clamp_max(self.depth_emb.num_embeddings - 1))
            a = a + self.count_emb(count.clamp_max(self.count_emb.num_embeddings - 1))
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
        latent_dim: latent width.
        topo_context: add depth and child-count embeddings to the topology head.
        type_mask: optional ``[num_types, d]`` bool (``FeatureSet.type_mask()``): decoded nodes
            get zeros outside their type's columns, as real inputs have, so that decoding sees
            what teacher forcing saw. Default: every column belongs to every type.
        max_depth_embed: depths above this share the last depth embedding.
        max_children_embed: child counts above this share the last count embedding.
        inputs: ``"features"`` (eq. 9–10 as published) or ``"types"`` (module docstring).
        latent_inputs: add ``W^{zx} z`` to every node's GRU input (module docstring).
    """

    def __init__(self, feat_dim: int, num_types: int, hidden_dim: int, latent_dim: int,
                 topo_context: bool = True, type_mask: Tensor | None = None,
                 max_depth_embed: int = 32, max_children_embed: int = 16,
                 inputs: str = "features", latent_inputs: bool = False) -> None:
        super().__init__()
        if inputs not in INPUT_MODES:
            raise ValueError(f"decoder inputs must be one of {INPUT_MODES}, got {inputs!r}")
        self.feat_dim, self.num_types, self.hidden_dim = feat_dim, num_types, hidden_dim
        self.inputs = inputs
        in_dim = feat_dim if inputs == "features" else num_types
        self.proj = nn.Linear(in_dim, hidden_dim, bias=False)
        self.zin = nn.Linear(latent_dim, hidden_dim, bias=False) if latent_inputs else None
        self.cell = TreeGRUCell(hidden_dim)
        self.topo = TopoHead(in_dim, hidden_dim, latent_dim, topo_context, max_depth_embed,
                             max_children_embed)
        self.W1_l = nn.Linear(latent_dim, hidden_dim)
        self.W2_l = nn.Linear(hidden_dim, hidden_dim, bias=False)
        self.U_l = nn.Linear(hidden_dim, feat_dim)
        self.U_c = nn.Linear(hidden_dim, num_types) if num_types > 1 else None
        mask = torch.ones(num_types, feat_dim, dtype=torch.bool) if type_mask is None else type_mask
        self.register_buffer("type_mask", mask.bool().clone(), persistent=False)

    def node_inputs(self, x: Tensor, node_type: Tensor) -> Tensor:
        """What the decoder reads of a node (``inputs``): its features, or its one-hot type."""
        if self.inputs == "features":
            return x
        return F.one_hot(node_type, self.num_types).to(x.dtype)

    def node_heads(self, zl: Tensor, h: Tensor) -> tuple[Tensor, Tensor]:
        """eq. 10–11: ``(features, type logits)`` from ``zl = W_1^l z`` and ``h = h_{p->c}``."""
        a = torch.relu(zl + self.W2_l(h))
        if self.U_c is None:
            return self.U_l(a), a.new_zeros(a.shape[0], 1)
        return self.U_l(a), self.U_c(a)

    # --- teacher forcing ----------------------------------------------------------------

    def teacher_forcing(self, z: Tensor, batch: Data, sched: TreeSchedule | None = None,
                        messages: tuple[Tensor, Tensor, Tensor] | None = None) -> DecoderOutput:
        """All predictions of the DFS trace of ``batch`` (normalised ``x``) given ``z`` ``[B, l]``.

        Messages are computed level by level (:func:`~robovae.model.tree.level_messages`), then
        every decision of the batch in one call of the topology head. ``messages`` (``(down,
        total, sdown)`` of this decoder's cell, level order, ``[N, H]`` each) skips the message
        passes when they were already computed (e.g. together with the encoder's; not possible
        with ``latent_inputs``, where the messages depend on ``z``).
        """
        sched = tree_schedule(batch) if sched is None else sched
        xin = self.node_inputs(batch.x, batch.node_type)
        if messages is None:
            px = self.project_levels(xin, sched, z)
            messages = tuple(t[0] for t in level_messages([self.cell], px[None], sched, 0))
        down, total, sdown = messages
        node, count, target, which, graph = decision_index(sched)
        inward_t = torch.cat([sdown, total]).index_select(0, which)
        logits = self.topo(xin.index_select(0, node), self.topo.W2(z).index_select(0, graph),
                           inward_t, sched.depth.index_select(0, node), count)
        feat, types = self.node_heads(self.W1_l(z).index_select(0, sched.graph),
                                      down.index_select(0, sched.inv))
        return DecoderOutput(logits, target, graph, node, feat, types)

    def project_levels(self, x: Tensor, sched: TreeSchedule, z: Tensor | None = None) -> Tensor:
        """``cell.project(x^p)`` with the rows in level order, ``[N, 3H]``; ``x`` is the
        :meth:`node_inputs` of the batch (node order), ``z`` (``[B, l]``) is required with
        ``latent_inputs``."""
        x = x.index_select(0, sched.order)
        if self.zin is None:
            return self.cell.project(x, self.proj.weight)
        if z is None:
            raise ValueError("a decoder with latent_inputs needs z to project its inputs")
        zx = self.zin(z).index_select(0, sched.graph.index_select(0, sched.order))
        return self.cell.project(self.proj(x) + zx)

    forward = teacher_forcing

    # --- greedy decoding ----------------------------------------------------------------

    @torch.no_grad()
    def decode(self, z: Tensor, max_nodes: int = 256,
               max_depth: int = 64) -> list[tuple[Tensor, Tensor, Tensor]]:
        """Greedy autoregressive decoding of ``z`` ``[B, l]`` (or ``[l]``), batched over latents.

        Every active latent advances one DFS step per iteration (one GRU call for all): expand
        when ``p > 0.5`` (and the tree has fewer than ``max_nodes`` nodes and the child's depth
        would be at most ``max_depth``), else backtrack; a tree is finished when its root
        backtracks or it reaches ``max_nodes``. Each tree takes at most ``2 * max_nodes - 1``
        steps, so decoding always terminates. Node types are ``argmax`` of the type logits.

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
        buf = _NodeBuffer(b * min(max_nodes, 32), self.feat_dim, hid, z.dtype, dev)
        zl, zt = self.W1_l(z), self.topo.W2(z)
        zx = self.zin(z) if self.zin is not None else None
        lat = torch.arange(b, device=dev)
        feat, types = self._new_nodes(zl, z.new_zeros(b, hid))
        cur = buf.add(lat, torch.full_like(lat, -1), torch.zeros_like(lat), types, feat,
                      self._px(feat, types, zx), z.new_zeros(b, hid))
        count = torch.ones_like(lat)
        active = count < max_nodes
        for _ in range(2 * max_nodes):
            act = active.nonzero().flatten()
            if act.numel() == 0:
                break
            i = cur[act]
            inward = buf.down[i] + buf.csum[i]
            logit = self.topo(self.node_inputs(buf.x[i], buf.type[i]), zt[act], inward,
                              buf.depth[i], buf.nchild[i])
            expand = (logit > 0) & (buf.depth[i] < max_depth)
            pxi = buf.px[i]
            s = torch.where(expand[:, None], inward, buf.csum[i])
            g = buf.cgated[i] + torch.where(expand[:, None], self.cell.gate_p(pxi, buf.down[i]),
                                            0.0)
            h = self.cell.step(pxi, s, g)
            e, k = expand.nonzero().flatten(), (~expand).nonzero().flatten()
            if e.numel():  # expanders create a child and move into it
                be, pe = act[e], i[e]
                feat, types = self._new_nodes(zl[be], h[e])
                px = self._px(feat, types, None if zx is None else zx[be])
                cur[be] = buf.add(be, pe, buf.depth[pe] + 1, types, feat, px, h[e])
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

    def _px(self, x: Tensor, node_type: Tensor, zx: Tensor | None = None) -> Tensor:
        xp = self.proj(self.node_inputs(x, node_type))
        return self.cell.project(xp if zx is None else xp + zx)

    def _new_nodes(self, zl: Tensor, h: Tensor) -> tuple[Tensor, Tensor]:
        feat, logits = self.node_heads(zl, h)
        types = logits.argmax(-1)
        return torch.where(self.type_mask[types], feat, torch.zeros_like(feat)), types


class _NodeBuffer:
    """Growable flat storage of the nodes being decoded (all latents interleaved)."""

    def __init__(self, cap: int, d: int, hid: int, dtype: torch.dtype,
                 dev: torch.device) -> None:
        self.n = 0
        long = {"dtype": torch.long, "device": dev}
        flt = {"dtype": dtype, "device": dev}
        self.owner, self.parent = torch.zeros(cap, **long), torch.zeros(cap, **long)
        self.depth, self.type = torch.zeros(cap, **long), torch.zeros(cap, **long)
        self.nchild = torch.zeros(cap, **long)
        self.x = torch.zeros(cap, d, **flt)
        self.px, self.down = torch.zeros(cap, 3 * hid, **flt), torch.zeros(cap, hid, **flt)
        self.csum, self.cgated = torch.zeros(cap, hid, **flt), torch.zeros(cap, hid, **flt)

    _FIELDS = ("owner", "parent", "depth", "type", "nchild", "x", "px", "down", "csum", "cgated")

    def add(self, owner: Tensor, parent: Tensor, depth: Tensor, types: Tensor, x: Tensor,
            px: Tensor, down: Tensor) -> Tensor:
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
        self.x[ids], self.px[ids], self.down[ids] = x, px, down
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
