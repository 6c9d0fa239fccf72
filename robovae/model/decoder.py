"""Depth-first tree decoder (paper §4.3, eq. 9–11): the tree comes from ``z``, per-node latents
refine the continuous features only. Teacher forcing and batched greedy decoding.

The robot latent has two parts, ``z = [z_T, z_G]`` (after JT-VAE's tree and graph latents):
the **tree latent** ``z_T`` (the first ``tree_latent_dim`` numbers; its encoder reads the tree
and the node types only) and the rest. The decoder walks a tree depth-first, like JT-VAE's DFS
trace. Node ``i`` is read as its one-hot type ``e_i`` together with the tree latent,
``x_i^p = W^p [e_i, z_T]``, and its own :class:`~robovae.model.tree.TreeGRUCell` passes
messages:

- up message (sent when the walk backtracks from ``c``):
  ``h_{c->p} = GRU(x_c^p, {h_{k->c}}_{k child of c})``;
- down message (sent when ``p`` expands into ``c``):
  ``h_{p->c} = GRU(x_p^p, {h_{parent(p)->p}} + {h_{k->p}}_{k earlier sibling of c})``.

A node with ``K`` children makes ``K + 1`` topology decisions: on arrival and after returning
from each child; the first ``K`` are "expand" (1), the last "backtrack" (0). **Structure reads
the tree latent and the tree decoded so far, nothing else**: with ``m`` the sum of the
messages node ``i`` has received at the decision, ``k`` its children so far and ``d_i`` its
depth (eq. 9, 11):

.. math::
    p_t = \\sigma(u \\cdot \\mathrm{ReLU}(W_z z_T + W_m m + E_t(t_i) + E_d(d_i) + E_k(k)
          + k\\,c)), \\qquad
    s_c = U^c\\, \\mathrm{ReLU}(W^c_z z_T + W^c_h h_{p \\to c} + E^c_d(d_c))

(embeddings clamped at ``max_depth_embed`` / ``max_children_embed``; the linear ``k c`` lets
counts beyond the embedded ones extrapolate). Features (eq. 10) read all of ``z``, the parent's
message, the node's type and its latent ``w_c`` (``node_latent_dim`` wide; posterior from
:class:`~robovae.model.encoder.TreeEncoder`), with a linear path from ``w_c``:

.. math::
    a = \\mathrm{ReLU}(W_1^l z + W_2^l h_{p \\to c} + W_3^l w_c + E^l_t(t_c)), \\qquad
    f_c = U^l a + V^l w_c

(the root has ``h = 0``). With ``feature_layers = L > 1`` the feature head is deeper:
``a <- a + ReLU(F_k a)`` for ``k = 1 .. L - 1`` before ``U^l``. The node latents have a
learned conditional prior:

.. math:: p(w_c \\mid z, h_{p \\to c}, t_c) = \\mathcal N(\\mu^p, \\mathrm{diag}\\, e^{\\lambda^p}),
          \\quad [\\mu^p, \\lambda^p] = U^p \\mathrm{ReLU}(W_1^p z + W_2^p h_{p \\to c}
          + E^p_t(t_c))

(``lambda^p`` soft-clamped to ``(-10, 10)``). Decoding "from z" puts every ``w_c`` at its prior
mean; since no structural head reads ``w`` or ``z_G``, the tree and its node types are a
function of ``z_T`` alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TypedDict

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
        prior_mu, prior_logvar: ``[N, node_latent_dim]`` the node latents' conditional prior.
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
    """Expansion logit of a decision from ``z``, the deciding node's received messages, its
    type, depth and number of children so far (module docstring)."""

    def __init__(self, hidden_dim: int, tree_latent_dim: int, num_types: int,
                 max_depth_embed: int, max_children_embed: int) -> None:
        super().__init__()
        self.W_z = nn.Linear(tree_latent_dim, hidden_dim)
        self.W_m = nn.Linear(hidden_dim, hidden_dim, bias=False)
        self.type_emb = nn.Embedding(num_types, hidden_dim)
        self.depth_emb = nn.Embedding(max_depth_embed + 1, hidden_dim)
        self.count_emb = nn.Embedding(max_children_embed + 1, hidden_dim)
        self.count_vec = nn.Parameter(torch.zeros(hidden_dim))
        self.u = nn.Linear(hidden_dim, 1)

    def forward(self, zt: Tensor, m: Tensor, node_type: Tensor, depth: Tensor,
                count: Tensor) -> Tensor:
        """Logits ``[M]`` of ``M`` decisions: ``zt = W_z z_T`` of each decision's robot
        ``[M, H]``, received messages ``m`` ``[M, H]``, the deciding nodes' types, depths and
        child counts so far ``[M]``."""
        a = zt + self.W_m(m) + self.type_emb(node_type)
        a = a + self.depth_emb(depth.clamp_max(self.depth_emb.num_embeddings - 1))
        a = a + self.count_emb(count.clamp_max(self.count_emb.num_embeddings - 1))
        a = a + count[:, None].to(a.dtype) * self.count_vec
        return self.u(torch.relu(a)).squeeze(-1)


def decision_index(sched: TreeSchedule) -> tuple[Tensor, Tensor, Tensor, Tensor, Tensor]:
    """The ``T = 2N - B`` topology decisions of a batch in DFS-trace order (cached on ``sched``).

    Returns ``(node, count, target, which, graph)``: deciding node, its number of children so
    far, label (1 expand / 0 backtrack), row of the decision's inward message sum in
    ``cat([sdown, total])`` (level order, :func:`~robovae.model.messages.level_messages`) and
    graph.
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
        tree_latent_dim: width of the tree latent ``z_T``, the first columns of ``z``
            (``1 <= tree_latent_dim <= latent_dim``; ``None``: all of ``z``).
        type_mask: optional ``[num_types, d]`` bool (``FeatureSet.type_mask()``): decoded nodes
            get zeros outside their type's columns, as real inputs have. Default: every column
            belongs to every type.
        max_depth_embed: depths above this share the last depth embedding.
        max_children_embed: child counts above this share the last count embedding.
        feature_layers: hidden layers of the feature head (at least 1; module docstring).

    Raises:
        ValueError: ``node_latent_dim < 1``, ``feature_layers < 1`` or ``tree_latent_dim``
            outside ``[1, latent_dim]``.
    """

    type_mask: Tensor  # [num_types, d] bool buffer (register_buffer in __init__)

    def __init__(self, feat_dim: int, num_types: int, hidden_dim: int, latent_dim: int,
                 node_latent_dim: int, tree_latent_dim: int | None = None,
                 type_mask: Tensor | None = None,
                 max_depth_embed: int = 32, max_children_embed: int = 16,
                 feature_layers: int = 1) -> None:
        super().__init__()
        if feature_layers < 1:
            raise ValueError(f"the feature head needs feature_layers >= 1, got {feature_layers}")
        if node_latent_dim < 1:
            raise ValueError(f"the decoder needs node latents (node_latent_dim >= 1), "
                             f"got {node_latent_dim}")
        tree_latent_dim = latent_dim if tree_latent_dim is None else tree_latent_dim
        if not 1 <= tree_latent_dim <= latent_dim:
            raise ValueError(f"tree_latent_dim must be in [1, latent_dim={latent_dim}], "
                             f"got {tree_latent_dim}")
        self.tree_latent_dim = tree_latent_dim
        self.feat_dim, self.num_types, self.hidden_dim = feat_dim, num_types, hidden_dim
        self.node_latent_dim = node_latent_dim
        self.proj = nn.Linear(num_types + tree_latent_dim, hidden_dim, bias=False)
        self.cell = TreeGRUCell(hidden_dim)
        self.topo = TopoHead(hidden_dim, tree_latent_dim, num_types, max_depth_embed,
                             max_children_embed)
        # node type (eq. 11)
        self.W_cz = nn.Linear(tree_latent_dim, hidden_dim)
        self.W_ch = nn.Linear(hidden_dim, hidden_dim, bias=False)
        self.depth_c = nn.Embedding(max_depth_embed + 1, hidden_dim)
        self.U_c = nn.Linear(hidden_dim, num_types) if num_types > 1 else None
        # features (eq. 10)
        self.W1_l = nn.Linear(latent_dim, hidden_dim)
        self.W2_l = nn.Linear(hidden_dim, hidden_dim, bias=False)
        self.W3_l = nn.Linear(node_latent_dim, hidden_dim, bias=False)
        self.type_l = nn.Embedding(num_types, hidden_dim)
        self.F_l = nn.ModuleList(nn.Linear(hidden_dim, hidden_dim)
                                 for _ in range(feature_layers - 1))
        self.U_l = nn.Linear(hidden_dim, feat_dim)
        self.V_l = nn.Linear(node_latent_dim, feat_dim, bias=False)
        # the node latents' conditional prior
        self.W1_p = nn.Linear(latent_dim, hidden_dim)
        self.W2_p = nn.Linear(hidden_dim, hidden_dim, bias=False)
        self.type_p = nn.Embedding(num_types, hidden_dim)
        self.U_p = nn.Linear(hidden_dim, 2 * node_latent_dim)
        mask = torch.ones(num_types, feat_dim, dtype=torch.bool) if type_mask is None else type_mask
        self.register_buffer("type_mask", mask.bool().clone(), persistent=False)

    # --- heads ---------------------------------------------------------------------------

    def type_logits(self, zc: Tensor, h: Tensor, depth: Tensor) -> Tensor:
        """Type logits ``[M, num_types]`` of new nodes from ``zc = W^c_z z_T``, their parent's
        message ``h`` and their depth (zeros with a single type)."""
        if self.U_c is None:
            return h.new_zeros(h.shape[0], 1)
        d = depth.clamp_max(self.depth_c.num_embeddings - 1)
        return self.U_c(torch.relu(zc + self.W_ch(h) + self.depth_c(d)))

    def features(self, zl: Tensor, h: Tensor, w: Tensor, node_type: Tensor) -> Tensor:
        """Features ``[M, d]`` of new nodes (eq. 10, module docstring) from ``zl = W_1^l z``,
        the parent's message ``h``, the node latents ``w`` and the nodes' types."""
        a = torch.relu(zl + self.W2_l(h) + self.W3_l(w) + self.type_l(node_type))
        for layer in self.F_l:
            a = a + torch.relu(layer(a))
        return self.U_l(a) + self.V_l(w)

    def node_prior(self, zp: Tensor, h: Tensor, node_type: Tensor) -> tuple[Tensor, Tensor]:
        """``(mu^p, logvar^p)`` of the node latents' prior (module docstring) from
        ``zp = W_1^p z``, the parent's message ``h`` and the nodes' types."""
        a = torch.relu(zp + self.W2_p(h) + self.type_p(node_type))
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
            px = self.project_levels(batch.node_type, z, sched)
            down_c, total_c, sdown_c = level_messages([self.cell], px[None], sched, 0)
            messages = (down_c[0], total_c[0], sdown_c[0])
        down, total, sdown = messages
        node, count, target, which, graph = decision_index(sched)
        m = torch.cat([sdown, total]).index_select(0, which)
        types, zt = batch.node_type, self.tree_part(z)
        logits = self.topo(self.topo.W_z(zt).index_select(0, graph), m,
                           types.index_select(0, node), sched.depth.index_select(0, node), count)
        h = down.index_select(0, sched.inv)
        g = sched.graph
        type_logits = self.type_logits(self.W_cz(zt).index_select(0, g), h, sched.depth)
        feat = self.features(self.W1_l(z).index_select(0, g), h, w, types)
        pmu, plogvar = self.node_prior(self.W1_p(z).index_select(0, g), h, types)
        return DecoderOutput(logits, target, graph, node, feat, type_logits, pmu, plogvar)

    def tree_part(self, z: Tensor) -> Tensor:
        """``z_T``: the first ``tree_latent_dim`` columns of ``z`` ``[B, latent_dim]``."""
        return z[:, :self.tree_latent_dim]

    def project_levels(self, node_type: Tensor, z: Tensor, sched: TreeSchedule) -> Tensor:
        """``cell.project(x^p)`` of the nodes' inputs ``[e_i, z_T]``, rows in level order,
        ``[N, 3H]``."""
        order = sched.order
        return self._px(node_type.index_select(0, order),
                        z.index_select(0, sched.graph.index_select(0, order)))

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

        The tree and the types depend on ``z_T`` only. The ``t``-th node created for latent ``b``
        (pre-order) takes ``node_latents[b][t]`` when given (reconstruction: the encoder's node
        means) and not NaN, else a draw from its conditional prior,
        ``mu^p + sigma^p * node_noise[b, t]`` (``node_noise`` is ``[B, >= max_nodes,
        node_latent_dim]``, already scaled by the sampling temperature), or the prior mean
        ``mu^p`` without ``node_noise``. (A row of NaN lets a caller give the latents of some
        nodes only, e.g. the nodes a variation shares with the robot it varies.)

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
        # room for 64 nodes a latent (the default model's robots have 39 on average): rows
        # never used cost address space only, a buffer that grows copies every row
        buf = _NodeBuffer(b * min(max_nodes, 64), self.feat_dim, hid, z.dtype, dev)
        heads = _LatentHeads(self, z, node_latents, node_noise, max_nodes)
        lat = torch.arange(b, device=dev)
        h0 = z.new_zeros(b, hid)
        types, feat = heads.new_nodes(lat, torch.zeros_like(lat), h0, torch.zeros_like(lat))
        cur = buf.add(lat, torch.full_like(lat, -1), torch.zeros_like(lat), types, feat,
                      self._px(types, z), h0)
        count = torch.ones_like(lat)
        active = count < max_nodes
        for _ in range(2 * max_nodes):
            act = active.nonzero().flatten()
            if act.numel() == 0:
                break
            i = cur[act]
            inward = buf.down[i] + buf.csum[i]
            logit = self.topo(heads.zt[act], inward, buf.type[i], buf.depth[i], buf.nchild[i])
            expand = (logit > 0) & (buf.depth[i] < max_depth)
            pxi = buf.px[i]
            s = torch.where(expand[:, None], inward, buf.csum[i])
            g = buf.cgated[i] + torch.where(expand[:, None], self.cell.gate_p(pxi, buf.down[i]),
                                            0.0)
            h = self.cell.step(pxi, s, g)
            e, k = expand.nonzero().flatten(), (~expand).nonzero().flatten()
            if e.numel():  # expanders create a child and move into it
                be, pe, he = act[e], i[e], h[e]
                depth = buf.depth[pe] + 1
                types, feat = heads.new_nodes(be, count[be], he, depth)
                cur[be] = buf.add(be, pe, depth, types, feat, self._px(types, z[be]), he)
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

    def _px(self, node_type: Tensor, z: Tensor) -> Tensor:
        """``cell.project(W^p [e_t, z_T])`` of nodes of types ``node_type`` in robots ``z``."""
        x = torch.cat([F.one_hot(node_type, self.num_types).to(z.dtype), self.tree_part(z)], -1)
        return self.cell.project(x, self.proj.weight)


class _LatentHeads:
    """The per-robot parts of greedy decoding: ``z``'s projections for every head, and where
    each new node's latent ``w`` comes from (the given latents of the robot while they last,
    pre-order index ``t``, unless a row is NaN; else the conditional prior)."""

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
        zt = dec.tree_part(z)
        self.zt, self.zc = dec.topo.W_z(zt), dec.W_cz(zt)
        self.zl, self.zp = dec.W1_l(z), dec.W1_p(z)
        given = list(given) if given is not None else []
        for k, g in enumerate(given):
            if g.dim() != 2 or g.shape[1] != self.dim:
                raise ValueError(f"node_latents[{k}] must be [n, {self.dim}], "
                                 f"got {list(g.shape)}")
        lens = [int(g.shape[0]) for g in given] or [0] * b
        self.lens = torch.tensor(lens, dtype=torch.long, device=z.device)
        self.table = z.new_zeros(b, max(lens, default=0), self.dim)
        self.known = torch.zeros(b, max(lens, default=0), dtype=torch.bool, device=z.device)
        for k, g in enumerate(given):
            self.table[k, :g.shape[0]] = g.to(z)
            self.known[k, :g.shape[0]] = ~torch.isnan(g).any(-1).to(z.device)
        self.table = torch.nan_to_num(self.table)

    def new_nodes(self, rows: Tensor, t: Tensor, h: Tensor,
                  depth: Tensor) -> tuple[Tensor, Tensor]:
        """``(types, features)`` of new nodes number ``t`` of robots ``rows`` (parent message
        ``h``, depth ``depth``): the type from ``z`` first, then the latent, then the
        features (zero outside the type's columns)."""
        dec = self.dec
        types = dec.type_logits(self.zc[rows], h, depth).argmax(-1)
        tt = t.clamp_max(max(self.table.shape[1] - 1, 0))
        have = (t < self.lens[rows]) & (self.known[rows, tt] if self.known.numel()
                                        else torch.zeros_like(t, dtype=torch.bool))
        if bool(have.all()):  # reconstruction: every node's latent is given, no prior needed
            w = self.table[rows, t]
        else:
            mu, logvar = dec.node_prior(self.zp[rows], h, types)
            w = mu
            if self.noise is not None:
                w = mu + torch.exp(0.5 * logvar) * self.noise[rows, t]
            if bool(have.any()):
                w = torch.where(have[:, None], self.table[rows, tt], w)
        feat = dec.features(self.zl[rows], h, w, types)
        return types, torch.where(dec.type_mask[types], feat, torch.zeros_like(feat))


class _TensorKwargs(TypedDict):
    """The ``dtype`` and ``device`` keyword arguments of a tensor factory."""

    dtype: torch.dtype
    device: torch.device


class _NodeBuffer:
    """Growable flat storage of the nodes being decoded (all latents interleaved)."""

    def __init__(self, cap: int, d: int, hid: int, dtype: torch.dtype,
                 dev: torch.device) -> None:
        self.n = 0
        long: _TensorKwargs = {"dtype": torch.long, "device": dev}
        flt: _TensorKwargs = {"dtype": dtype, "device": dev}
        # uninitialised: every field of a row is written when its node is added (add), so the
        # memory of rows never used is never touched (docs/generation.md, "The decoder's
        # buffer")
        self.owner, self.parent = torch.empty(cap, **long), torch.empty(cap, **long)
        self.depth, self.type = torch.empty(cap, **long), torch.empty(cap, **long)
        self.nchild = torch.empty(cap, **long)
        self.x = torch.empty(cap, d, **flt)
        self.px, self.down = torch.empty(cap, 3 * hid, **flt), torch.empty(cap, hid, **flt)
        self.csum, self.cgated = torch.empty(cap, hid, **flt), torch.empty(cap, hid, **flt)

    _FIELDS = ("owner", "parent", "depth", "type", "nchild", "x", "px", "down", "csum",
               "cgated")

    def add(self, owner: Tensor, parent: Tensor, depth: Tensor, types: Tensor, x: Tensor,
            px: Tensor, down: Tensor) -> Tensor:
        """Append nodes (children's ``nchild``/``csum``/``cgated`` start at zero); their ids."""
        m = owner.numel()
        if self.n + m > self.owner.shape[0]:
            cap = max(2 * self.owner.shape[0], self.n + m)
            for f in self._FIELDS:
                old = getattr(self, f)
                new = old.new_empty((cap, *old.shape[1:]))
                new[: self.n] = old[: self.n]
                setattr(self, f, new)
        ids = torch.arange(self.n, self.n + m, device=owner.device)
        self.owner[ids], self.parent[ids], self.depth[ids], self.type[ids] = (
            owner, parent, depth, types)
        self.x[ids], self.px[ids], self.down[ids] = x, px, down
        fresh = slice(self.n, self.n + m)  # a new node has no children yet
        self.nchild[fresh], self.csum[fresh], self.cgated[fresh] = 0, 0.0, 0.0
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
