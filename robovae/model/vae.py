"""``RoboVAE``: the tree-MPNN VAE as a LightningModule (paper §4.2–4.3).

The module owns the feature :class:`~robovae.data.normalizer.Normalizer` (fitted on the training
split by the datamodule and stored in every checkpoint), so ``RoboVAE.load_from_checkpoint``
alone can encode robot files and decode robots in physical units.

Loss (eq. 12–13):  L = Σ_t BCE(p_t, p̂_t) + Σ_j [MSE(f_j, f̂_j) + CE(s_j, ŝ_j)] + β L_KL,
with β linearly warmed up from ``beta_start`` to ``beta`` over ``beta_warmup_epochs``, plus the
node latents' ``β_w Σ_j KL(q(w_j | G) || p(w_j | z, h_{p→j}, w_p))`` (:mod:`robovae.model.loss`;
the BCE, CE and KL terms in nats, the MSE in normalised feature units squared).

Reproducible training: the randomness of an epoch — the shuffle order of a single-process
training loader (a ``RandomSampler``), the reparametrisation noise of each batch and the
datamodule's augmentation (:mod:`robovae.data.augment`) — is drawn from generators seeded by the
run's seed (``seed_everything``), the epoch, the batch index and the rank
(:func:`~robovae.data.augment.run_seed`), never from the global RNG. A run killed and resumed
from an end-of-epoch checkpoint (``robovae fit ... --ckpt_path last``) therefore continues
exactly like an uninterrupted run.
Under DDP, Lightning's ``DistributedSampler`` shuffles by ``(seed, epoch)`` already.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import lightning as L
import torch
from lightning.pytorch.utilities.types import STEP_OUTPUT, OptimizerLRScheduler
from torch import Tensor
from torch.utils.data import DataLoader, RandomSampler
from torch_geometric.data import Batch, Data

from robovae.data.augment import NOISE, SHUFFLE, run_seed
from robovae.data.features import get_feature_set
from robovae.data.graph import RobotData, tree_data
from robovae.data.normalizer import Normalizer
from robovae.errors import RobovaeError
from robovae.model.architecture import check_architecture
from robovae.model.decoder import TreeDecoder
from robovae.model.encoder import TreeEncoder, reparametrize
from robovae.model.latent_mixture import LatentMixture, fit_to_robots
from robovae.model.loss import vae_loss
from robovae.model.messages import level_messages
from robovae.model.prior import draw_robots
from robovae.model.records import from_columns, to_columns
from robovae.model.sampling import PriorSampling
from robovae.model.tree import TreeSchedule, tree_schedule
from robovae.settings import FEATURE_SET, check_settings, choice, integer, number


def _draw(mu: Tensor, logvar: Tensor, sample: bool,
          generator: torch.Generator | None) -> Tensor:
    """``mu`` (no sampling), else ``mu + eps exp(logvar / 2)`` with ``eps`` from ``generator``
    (the global RNG when ``None``)."""
    if not sample:
        return mu
    if generator is None:
        return reparametrize(mu, logvar)
    eps = torch.randn(mu.shape, generator=generator, dtype=mu.dtype, device=mu.device)
    return mu + eps * torch.exp(0.5 * logvar)


#: Sampling priors of :meth:`RoboVAE.sample_prior`.
PRIORS = ("mixture", "standard")
#: Learning-rate schedules of :meth:`RoboVAE.configure_optimizers`.
LR_SCHEDULES = ("cosine", "constant")


class RoboVAE(PriorSampling, L.LightningModule):
    """Tree-GRU VAE over robot graphs.

    Args:
        feature_set: registry name of the node features (must match the data).
        hidden_dim: message / hidden size of encoder and decoder.
        latent_dim: size of z = [z_T, z_G].
        tree_latent_dim: size of the tree latent z_T, the first columns of z: its encoder reads
            the tree and the node types only, and the decoder's structural heads (topology and
            node types) read nothing else (:mod:`robovae.model.decoder`); z_G (the rest) is
            read from the features and shapes the features only. Must be below ``latent_dim``
            (``None``: half of it).
        beta: final weight of the KL term (eq. 13).
        beta_start: β at epoch 0 of the linear warm-up.
        beta_warmup_epochs: epochs of the linear warm-up from ``beta_start`` to ``beta``.
        lr: AdamW learning rate.
        weight_decay: AdamW weight decay.
        lr_schedule: ``cosine`` (to ``lr * lr_min_factor`` over ``max_epochs``) or ``constant``.
        lr_min_factor: final learning rate as a fraction of ``lr`` for the cosine schedule.
        max_nodes: node limit of autoregressive decoding.
        max_depth: depth limit of autoregressive decoding.
        support_margin: decoded features are clipped to the training range of each column
            widened by this fraction of its width (``None``: no clipping). Keeps prior samples
            on the support of the data: a log-scaled mass far outside it would be e^20 kg.
        node_latent_dim: width of the per-node latents ``w`` (at least 1): the encoder gives
            every node a posterior, the decoder reads it in the node's feature head only and
            learns a conditional prior for generation (:mod:`robovae.model.decoder`).
        beta_nodes: weight of the node latents' KL (``None``: follow β and its warm-up).
        prior_components: components of the :class:`~robovae.model.latent_mixture.
            LatentMixture` fitted to the training robots' posterior means at the end of
            training (0: none).
        prior: the sampling prior of :meth:`sample_prior` and :meth:`sample`: ``mixture``
            (that mixture, when fitted) or ``standard`` (``N(0, I)``, the VAE's own prior).
        feature_layers: hidden layers of the decoder's feature head
            (:mod:`robovae.model.decoder`).
        node_temperature: the node latents' sampling temperature (``None``: the temperature of
            ``z``; ``0``: every node at its conditional prior mean): a sampling setting only
            (:mod:`robovae.model.sampling`), training ignores it.
    """

    # Lightning's ``dtype`` property (types it ``str | torch.dtype``: a string only after
    # ``Module.type("...")``, never used on this model; ``.to()``/``.double()`` keep a
    # ``torch.dtype``, which decoding and sampling need): declared, not defined here
    dtype: torch.dtype

    def __init__(
        self,
        feature_set: str = "paper34",
        hidden_dim: int = 128,
        latent_dim: int = 32,
        beta: float = 1e-3,
        beta_start: float = 0.0,
        beta_warmup_epochs: int = 0,
        lr: float = 1e-3,
        weight_decay: float = 0.0,
        lr_schedule: str = "cosine",
        lr_min_factor: float = 0.05,
        max_nodes: int = 256,
        max_depth: int = 64,
        support_margin: float | None = 0.1,
        node_latent_dim: int = 32,
        beta_nodes: float | None = None,
        tree_latent_dim: int | None = None,
        prior_components: int = 64,
        prior: str = "mixture",
        feature_layers: int = 1,
        node_temperature: float | None = None,
    ) -> None:
        super().__init__()
        self.save_hyperparameters()
        check_settings(
            "model", feature_set=(feature_set, FEATURE_SET), hidden_dim=(hidden_dim, integer(1)),
            latent_dim=(latent_dim, integer(2)),
            beta=(beta, number(0)), beta_start=(beta_start, number(0)),
            beta_warmup_epochs=(beta_warmup_epochs, integer(0)),
            lr=(lr, number(0, low_open=True)), weight_decay=(weight_decay, number(0)),
            lr_schedule=(lr_schedule, choice(LR_SCHEDULES)),
            lr_min_factor=(lr_min_factor, number(0, 1)), max_nodes=(max_nodes, integer(1)),
            max_depth=(max_depth, integer(0)),
            support_margin=(support_margin, number(0).or_none()),
            node_latent_dim=(node_latent_dim, integer(1)),
            beta_nodes=(beta_nodes, number(0).or_none()),
            tree_latent_dim=(tree_latent_dim, integer(1).or_none()),
            prior_components=(prior_components, integer(0)), prior=(prior, choice(PRIORS)),
            feature_layers=(feature_layers, integer(1)),
            node_temperature=(node_temperature, number(0).or_none()))
        self.latent_mixture = LatentMixture(latent_dim, prior_components) \
            if prior_components > 0 else None
        fs = get_feature_set(feature_set)
        self.feature_set = fs
        self.normalizer = Normalizer(fs)
        if tree_latent_dim is None:
            tree_latent_dim = self.hparams.tree_latent_dim = max(1, latent_dim // 2)
        if not 1 <= tree_latent_dim < latent_dim:
            raise ValueError(f"robovae: tree_latent_dim must be in [1, latent_dim), got "
                             f"{tree_latent_dim} with latent_dim {latent_dim}")
        self.tree_encoder = TreeEncoder(fs.num_node_types, hidden_dim, tree_latent_dim,
                                        reads_types=True)
        self.encoder = TreeEncoder(fs.dim, hidden_dim, latent_dim - tree_latent_dim,
                                   node_latent_dim)
        self.decoder = TreeDecoder(fs.dim, fs.num_node_types, hidden_dim, latent_dim,
                                   node_latent_dim, tree_latent_dim, type_mask=fs.type_mask(),
                                   feature_layers=feature_layers)
        self.training_robots: list[dict] = []

    # --- data in model units -------------------------------------------------------------

    def setup(self, stage: str) -> None:
        """Take the datamodule's training-split normaliser unless the checkpoint brought one."""
        dm = getattr(self.trainer, "datamodule", None) if self._trainer else None
        norm = getattr(dm, "normalizer", None)
        if norm is not None and norm.feature_set.name != self.feature_set.name:
            raise ValueError(f"robovae: the model uses feature set {self.feature_set.name!r} "
                             f"but the data has {norm.feature_set.name!r}")
        if norm is not None and not bool(self.normalizer.fitted):
            self.normalizer.load_state_dict(norm.state_dict())
        if stage == "fit" and dm is not None and getattr(dm, "train_set", None) is not None:
            from robovae.evaluate.samples import robot_record

            self.training_robots = [robot_record(d, self.normalizer) for d in dm.train_set]

    def on_save_checkpoint(self, checkpoint: dict) -> None:
        """Keep the training robots' records (names, duplicate keys, descriptors: plain
        strings and numbers) so generation can measure novelty from the checkpoint alone,
        stored column by column (:func:`robovae.model.records.to_columns`: quick to load)."""
        checkpoint["robovae_training_robots"] = to_columns(self.training_robots)

    def on_load_checkpoint(self, checkpoint: dict) -> None:
        """Restore the training robots' records saved by :meth:`on_save_checkpoint` (or the
        plain list of an earlier version); a checkpoint from before the latent mixture loads
        with the mixture unfitted; a checkpoint of another architecture is refused in one line
        (:func:`~robovae.model.architecture.check_architecture`)."""
        self.training_robots = from_columns(checkpoint.get("robovae_training_robots"))
        state = checkpoint.get("state_dict", {})
        if self.latent_mixture is not None and "latent_mixture.fitted" not in state:
            state.update({f"latent_mixture.{k}": v
                          for k, v in self.latent_mixture.state_dict().items()})
        check_architecture(checkpoint, self, self._trainer.ckpt_path if self._trainer else None)

    def normalized(self, batch: Batch) -> Batch:
        """A shallow copy of ``batch`` whose ``x`` is in model units, plus the batch's
        ``x_jitter`` when it has one (:class:`~robovae.data.augment.FeatureJitter`)."""
        out = batch.clone()
        out.x = self.normalizer(batch.x.to(self.device), batch.node_type.to(self.device))
        jitter = getattr(batch, "x_jitter", None)
        if jitter is not None:
            out.x = out.x + jitter.to(out.x)
        return out

    # --- training ------------------------------------------------------------------------

    def beta_at(self, epoch: int) -> float:
        """β of an epoch: linear warm-up from ``beta_start`` to ``beta``."""
        hp = self.hparams
        if hp.beta_warmup_epochs <= 0:
            return hp.beta
        frac = min(1.0, epoch / hp.beta_warmup_epochs)
        return hp.beta_start + frac * (hp.beta - hp.beta_start)

    def beta_nodes_at(self, epoch: int) -> float:
        """β_w of an epoch: ``beta_nodes`` when set, else :meth:`beta_at`."""
        bn = self.hparams.get("beta_nodes")
        return self.beta_at(epoch) if bn is None else float(bn)

    def on_train_epoch_start(self) -> None:
        """Seed this epoch's shuffle order from ``(seed, epoch)`` (see the module docstring):
        the global RNG is not part of a checkpoint, the epoch is."""
        loaders = self.trainer.train_dataloader
        if isinstance(loaders, Mapping):
            loaders = list(loaders.values())
        elif not isinstance(loaders, Sequence):
            loaders = [loaders]
        for k, dl in enumerate(loaders):
            sampler = getattr(dl, "sampler", None) if isinstance(dl, DataLoader) else None
            if isinstance(sampler, RandomSampler):
                sampler.generator = torch.Generator().manual_seed(
                    run_seed(SHUFFLE, self.current_epoch, k, self.global_rank))

    def on_train_batch_end(self, outputs: STEP_OUTPUT, batch: Any, batch_idx: int) -> None:
        """After the last step of the last epoch (before its validation and checkpoint), fit
        the sampling mixture to the training robots' latents
        (:func:`~robovae.model.latent_mixture.fit_to_robots`; every process the same robots)."""
        trainer = self.trainer
        if self.latent_mixture is None or trainer.max_epochs is None \
                or self.current_epoch < trainer.max_epochs - 1 or not trainer.is_last_batch:
            return
        robots = getattr(getattr(trainer, "datamodule", None), "train_set", None)
        if robots is None:
            robots = getattr(trainer.train_dataloader, "dataset", None)
        if robots is not None:
            was_training = self.training
            self.eval()
            fit_to_robots(self.latent_mixture, self.encode, robots)
            self.train(was_training)

    def forward(self, batch: Batch, sample: bool = True,
                generator: torch.Generator | None = None) -> dict[str, Tensor]:
        """Loss terms of a batch of physical-unit robot graphs (teacher forcing). With
        ``sample``, ``z`` is drawn from ``q(z | G)`` (noise from ``generator`` when given).
        Training batches come augmented by the datamodule (:mod:`robovae.data.augment`)."""
        nb = self.normalized(batch)
        sched = tree_schedule(nb)
        mu, logvar, w_mu, w_logvar = self.posteriors(nb, sched)
        z = _draw(mu, logvar, sample, generator)
        w = _draw(w_mu, w_logvar, sample, generator)
        out = self.decoder.teacher_forcing(z, nb, w, sched)
        epoch = self.current_epoch
        return vae_loss(out, nb, mu, logvar, self.beta_at(epoch), w_mu, w_logvar,
                        self.beta_nodes_at(epoch), tree_dim=self.hparams.tree_latent_dim)

    def posteriors(self, nb: Batch, sched: TreeSchedule) -> tuple[Tensor, Tensor, Tensor,
                                                                     Tensor]:
        """``(mu, logvar, w_mu, w_logvar)`` of a normalised batch: ``q(z | G)`` ``[B, latent]``
        with ``z = [z_T, z_G]`` (tree encoder, feature encoder) and the node posteriors
        ``[N, node_latent_dim]`` (node order). The two encoders' level passes run stacked."""
        encs = (self.tree_encoder, self.encoder)
        xs = [e.inputs(nb, sched) for e in encs]
        px = torch.stack([e.project(x) for e, x in zip(encs, xs)])
        _, total, _ = level_messages([e.cell for e in encs], px, sched, num_encoder=2)
        (mt, lt), (mg, lg) = (e.readout(x, t, sched) for e, x, t in zip(encs, xs, total))
        w_mu, w_logvar = self.encoder.node_readout(xs[1], total[1], sched)
        return torch.cat([mt, mg], 1), torch.cat([lt, lg], 1), w_mu, w_logvar

    def _step(self, batch: Batch, stage: str, batch_idx: int = 0) -> Tensor:
        gen = None
        if stage == "train":  # noise of (seed, epoch, batch, rank): resumable, see the docstring
            gen = torch.Generator(device=self.device).manual_seed(
                run_seed(NOISE, self.current_epoch, batch_idx, self.global_rank))
        terms = self(batch, sample=stage == "train", generator=gen)
        bs = batch.num_graphs
        # sync_dist: under DDP the epoch value is the mean over all ranks' robots
        for k in ("loss", "topo", "feat", "type", "kl", "kl_tree", "kl_nodes"):
            self.log(f"{stage}/{k}", terms[k], batch_size=bs, prog_bar=k == "loss",
                     on_epoch=True, on_step=False, sync_dist=True)
        if stage == "train":
            self.log("train/beta", self.beta_at(self.current_epoch), batch_size=bs,
                     on_epoch=True, on_step=False, sync_dist=True)
        return terms["loss"]

    def training_step(self, batch: Batch, batch_idx: int) -> Tensor:
        """One optimisation step: the loss of :meth:`forward` on a (possibly augmented) batch."""
        return self._step(batch, "train", batch_idx)

    def validation_step(self, batch: Batch, batch_idx: int) -> Tensor:
        """Validation loss terms (reconstruction metrics come from the callback)."""
        return self._step(batch, "val")

    def test_step(self, batch: Batch, batch_idx: int) -> Tensor:
        """Test loss terms (reconstruction metrics come from the callback)."""
        return self._step(batch, "test")

    def predict_step(self, batch: Batch | dict, batch_idx: int) -> list[RobotData] | dict:
        """Reconstruct a batch of robots, or decode a batch of latent indices
        (:class:`~robovae.generate.predict.LatentIndices`: ``z_i`` from ``(seed, i)``)."""
        if not isinstance(batch, dict):
            return self.reconstruct(batch)
        seed, temp = int(batch["seed"][0]), float(batch["temperature"][0])
        redraws = int(batch["redraws"][0]) if "redraws" in batch else 0
        z, graphs, draws = draw_robots(self, seed, batch["index"].tolist(), temp,
                                       redraws=redraws)
        return {"index": batch["index"], "z": z, "graphs": graphs, "draws": draws,
                "seed": seed, "temperature": temp}

    def configure_optimizers(self) -> OptimizerLRScheduler:
        """AdamW; with ``lr_schedule="cosine"`` the rate follows
        ``lr_e = lr (f + (1 - f) (1 + cos(pi e / E)) / 2)``, ``f = lr_min_factor``."""
        hp = self.hparams
        opt = torch.optim.AdamW(self.parameters(), lr=hp.lr, weight_decay=hp.weight_decay)
        if hp.lr_schedule == "constant":
            return opt
        # (the constructor refused any other schedule)
        epochs = max(1, self.trainer.max_epochs or 1)
        floor = hp.lr_min_factor

        def factor(epoch: int) -> float:
            return floor + (1 - floor) * 0.5 * (1 + math.cos(math.pi * min(epoch, epochs) / epochs))

        sched = torch.optim.lr_scheduler.LambdaLR(opt, factor)
        return {"optimizer": opt, "lr_scheduler": {"scheduler": sched, "interval": "epoch"}}

    # --- the public API ------------------------------------------------------------------

    @torch.no_grad()
    def encode(self, batch: Batch | Data) -> tuple[Tensor, Tensor]:
        """``(mu, logvar)`` ``[B, latent_dim]`` of each robot of a (physical-unit) batch."""
        mu, logvar, _, _ = self._encode_all(batch)
        return mu, logvar

    @torch.no_grad()
    def encode_nodes(self, batch: Batch | Data) -> tuple[Tensor, list[Tensor]]:
        """``(mu, node_mu)``: each robot's latent mean ``[B, latent_dim]`` and its nodes' latent
        means in pre-order (a list of ``[n_i, node_latent_dim]``): what :meth:`reconstruct`
        decodes."""
        mu, _, w_mu, counts = self._encode_all(batch)
        return mu, list(torch.split(w_mu, counts))

    def _encode_all(self, batch: Batch | Data) -> tuple[Tensor, Tensor, Tensor, list[int]]:
        if not isinstance(batch, Batch):
            batch = Batch.from_data_list([batch])
        nb = self.normalized(batch.to(self.device))
        sched = tree_schedule(nb)
        mu, logvar, w_mu, _ = self.posteriors(nb, sched)
        return mu, logvar, w_mu, torch.bincount(sched.graph, minlength=sched.num_graphs).tolist()

    def check_latents(self, z: Tensor) -> Tensor:
        """``z`` as a ``[B, latent_dim]`` tensor of the model's dtype and device.

        Raises:
            RobovaeError: (one line) not a ``[B, latent_dim]`` or ``[latent_dim]`` array of
                numbers, or rows holding NaN or ±inf — also after conversion to the model's
                dtype (1e300 overflows float32).
        """
        dim = self.hparams.latent_dim
        try:
            z = torch.as_tensor(z)
        except Exception as e:  # lists of strings, ragged lists, ...
            raise RobovaeError(f"robovae: latents must be numbers ({type(e).__name__})") \
                from None
        shape = list(z.shape)
        if z.dim() == 1:
            z = z[None]
        if z.dim() != 2 or z.shape[1] != dim:
            raise RobovaeError(f"robovae: latents must have shape [B, {dim}] or [{dim}], "
                               f"got {shape}")
        if z.is_complex() or z.dtype == torch.bool:
            raise RobovaeError(f"robovae: latents must be real numbers, got {z.dtype}")
        z = z.to(self.device, self.dtype)
        bad = (~torch.isfinite(z)).any(1)
        if bool(bad.any()):
            rows = bad.nonzero().flatten().tolist()
            more = f" and {len(rows) - 10} more" if len(rows) > 10 else ""
            raise RobovaeError(f"robovae: latents must be finite {str(self.dtype)[6:]} values; "
                               f"rows {rows[:10]}{more} hold NaN or inf")
        return z

    @torch.no_grad()
    def decode(self, z: Tensor, max_nodes: int | None = None, max_depth: int | None = None,
               node_latents: Sequence[Tensor] | None = None, node_noise: Tensor | None = None,
               clamp: bool = True) -> list[RobotData]:
        """Greedy autoregressive decoding of latents ``z`` [B, latent] into robot graphs with
        physical feature values.

        ``node_latents`` (per robot ``[n_i, node_latent_dim]``, pre-order,
        e.g. from :meth:`encode_nodes`) are used for the first ``n_i`` nodes; the other nodes
        are drawn from their conditional prior, ``mu^p + sigma^p * node_noise[b, t]``
        (``node_noise``: ``[B, >= max_nodes, node_latent_dim]``, temperature included), or take
        the prior mean without ``node_noise``. ``clamp=False`` skips the ``support_margin``
        clipping (reconstruction of robots that lie outside the training range).

        Any latent the model can represent decodes within the limits (at most ``max_nodes``
        nodes, depth at most ``max_depth``; defaults from the hyperparameters), however large:
        huge values saturate the decoder (overflowing logits count as "backtrack"; with
        ``support_margin``, a feature that overflows to NaN becomes the column's training mean and
        ±inf the edge of its support). What cannot
        be decoded is refused with a one-line :class:`~robovae.errors.RobovaeError`: a wrong
        shape, NaN/inf rows (:meth:`check_latents`), or — only without ``support_margin`` — a
        latent so large that its decoded features overflow to NaN/inf (the rows are named).
        """
        hp = self.hparams
        max_nodes = hp.max_nodes if max_nodes is None else max_nodes
        max_depth = hp.max_depth if max_depth is None else max_depth
        if int(max_nodes) < 1 or int(max_depth) < 0:
            raise RobovaeError(f"robovae: decoding needs max_nodes >= 1 and max_depth >= 0, "
                               f"got {max_nodes} and {max_depth}")
        z = self.check_latents(z)
        if z.shape[0] == 0:
            return []
        if node_noise is not None:
            node_noise = torch.as_tensor(node_noise).to(self.device, self.dtype)
        trees = self.decoder.decode(z, max_nodes=int(max_nodes), max_depth=int(max_depth),
                                    node_latents=node_latents, node_noise=node_noise)
        out, bad = [], []
        for i, (parent, node_type, x) in enumerate(trees):
            if clamp and hp.support_margin is not None:  # saturated: NaN -> the training mean
                x = torch.nan_to_num(x, nan=0.0)
            phys = self.normalizer.inverse(x, node_type,
                                           clamp=hp.support_margin if clamp else None)
            out.append(tree_data(parent.cpu(), node_type.cpu(), phys.cpu(), self.feature_set,
                                 name=f"decoded_{i}", source="robovae.decode"))
            if not bool(torch.isfinite(out[-1].x).all()):  # (robot graphs hold float32)
                bad.append(i)
        if bad:
            more = f" and {len(bad) - 10} more" if len(bad) > 10 else ""
            raise RobovaeError(f"robovae: latents too large: rows {bad[:10]}{more} decode to "
                               "non-finite features (use a support_margin)")
        return out

    @torch.no_grad()
    def reconstruct(self, batch: Batch | Data, from_z: bool = False) -> list[RobotData]:
        """Encode (``z = mu``, node latents at their posterior means) and decode each robot;
        names follow the inputs. ``from_z``: decode ``z = mu`` alone, every node latent at the
        mean of its conditional prior (nothing read per node from the input): what the robot
        latent carries by itself."""
        if not isinstance(batch, Batch):
            batch = Batch.from_data_list([batch])
        mu, nodes = self.encode_nodes(batch)
        # no support clipping: a real robot may lie outside the training range
        out = self.decode(mu, node_latents=None if from_z else nodes, clamp=False)
        names = batch.name if isinstance(batch.name, list) else [batch.name]
        for d, name in zip(out, names):
            d.name = name
        return out

    @torch.no_grad()
    def latent_costs(self, batch: Batch | Data) -> dict[str, Tensor]:
        """Per robot, in nats: ``kl_z`` = KL(q(z | G) || N(0, I)), ``kl_tree`` its part over the
        tree latent ``z_T``, ``kl_nodes`` = the sum over its
        nodes of KL(q(w_i | G) || p(w_i | z, h, w_parent)), and ``nelbo_per_node`` = the negative
        ELBO (:func:`~robovae.model.loss.vae_loss`, teacher forcing at the posterior means)
        divided by the number of nodes; also ``nodes``. Tensors ``[B]``."""
        if not isinstance(batch, Batch):
            batch = Batch.from_data_list([batch])
        terms = self(batch.to(self.device), sample=False)
        nodes = torch.bincount(batch.batch.to(self.device), minlength=batch.num_graphs)
        return {"kl_z": terms["per_graph_kl"], "kl_tree": terms["per_graph_kl_tree"],
                "kl_nodes": terms["per_graph_kl_nodes"],
                "nelbo_per_node": terms["per_graph_nelbo"] / nodes.to(terms["per_graph_nelbo"]),
                "nodes": nodes}
