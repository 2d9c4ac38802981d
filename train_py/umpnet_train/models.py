"""The networks: PositionNet (per-pixel affordance) and DirectionNet (Dist and
AoT branches over an image encoder and an action decoder). `direction_net
"paper"` is the paper's DirectionNet; the default, "context", reads a U-Net's
embedding at the grasp pixel (see DirectionEncoder).

Observations enter as N x H x W x 10 (the Rust layout) and are normalised
inside the networks, so exported ONNX graphs take raw observations.
"""

from __future__ import annotations

import itertools

import torch
from torch import nn
from torch.nn import functional as F

CHANNELS = 10
# Channel statistics of the reference camera's observations: xyz around the
# object, rgb and normals in [-1, 1] ranges, depth around 2 m.
OBS_MEAN = [0.0, -0.5, 0.3, 0.5, 0.5, 0.5, 0.0, -0.5, 0.5, 2.2]
OBS_STD = [0.5, 0.5, 0.3, 0.25, 0.25, 0.25, 0.5, 0.5, 0.5, 0.6]
AOT_CLASSES = (-1, 0, 1)  # index -> Arrow-of-Time label


class Normalize(nn.Module):
    def __init__(self, repeats: int = 1):
        super().__init__()
        self.register_buffer("mean", torch.tensor(OBS_MEAN * repeats).view(1, -1, 1, 1))
        self.register_buffer("std", torch.tensor(OBS_STD * repeats).view(1, -1, 1, 1))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return (x - self.mean) / self.std


def block(cin: int, cout: int, stride: int = 1) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(cin, cout, 3, stride=stride, padding=1, bias=False),
        nn.BatchNorm2d(cout),
        nn.ReLU(inplace=True),
        nn.Conv2d(cout, cout, 3, padding=1, bias=False),
        nn.BatchNorm2d(cout),
        nn.ReLU(inplace=True),
    )


class UNet(nn.Module):
    """A small U-Net: widths[0] at full resolution, halving resolution per level.

    With `global_context`, the mean of the coarsest features is added to every
    output pixel: a small U-Net's receptive field does not span a whole object,
    yet whether a move heads away from the reference depends on where the part
    is as a whole (hinge side, how far it already moved)."""

    def __init__(self, cin: int, widths: tuple[int, ...], cout: int, global_context: bool = False):
        super().__init__()
        self.down = nn.ModuleList([block(cin, widths[0])])
        for a, b in itertools.pairwise(widths):
            self.down.append(block(a, b, stride=2))
        self.up = nn.ModuleList([block(b + a, a) for a, b in itertools.pairwise(widths)])
        self.head = nn.Conv2d(widths[0], cout, 1)
        self.context = nn.Linear(widths[-1], cout) if global_context else None

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.forward_with_features(x)[0]

    def forward_with_features(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The output and the full-resolution features the head reads."""
        skips = []
        for d in self.down:
            x = d(x)
            skips.append(x)
        x = skips.pop()
        context = None if self.context is None else self.context(x.mean(dim=(2, 3)))[:, :, None, None]
        for up in reversed(self.up):
            skip = skips.pop()
            x = F.interpolate(x, size=skip.shape[-2:], mode="bilinear", align_corners=False)
            x = up(torch.cat([x, skip], dim=1))
        return (self.head(x) if context is None else self.head(x) + context), x


class PositionNet(nn.Module):
    """Per-pixel two-class output: will acting here move the object?

    With `fields`, an auxiliary head on the same features predicts each pixel's
    articulation flow (3) and whether it is on a movable part (1 logit); the
    exported network (`forward`) stays the two-class map."""

    def __init__(self, widths: tuple[int, ...], fields: bool = False):
        super().__init__()
        self.norm = Normalize()
        self.unet = UNet(CHANNELS, widths, 2)
        self.fields_head = nn.Conv2d(widths[0], 4, 1) if fields else None

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        """observation N x H x W x 10 -> logits N x 2 x H x W."""
        return self.unet(self.norm(observation.permute(0, 3, 1, 2)))

    def forward_fields(self, observation: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(logits N x 2 x H x W, fields N x 4 x H x W: flow xyz, movable logit)."""
        logits, features = self.unet.forward_with_features(self.norm(observation.permute(0, 3, 1, 2)))
        return logits, self.fields_head(features)


def features_at(fmap: torch.Tensor, pixel: torch.Tensor) -> torch.Tensor:
    """fmap N x C x H x W, pixel N x 2 (row, col) int64 -> N x C."""
    n, c, h, w = fmap.shape
    index = (pixel[:, 0].clamp(0, h - 1) * w + pixel[:, 1].clamp(0, w - 1)).view(n, 1, 1).expand(n, c, 1)
    return torch.gather(fmap.reshape(n, c, h * w), 2, index).squeeze(2)


# Scales of the current-minus-reference channels (xyz, normal, depth): a part
# that moved by a few centimetres should read about 1.
DIFF_SCALE = [0.1, 0.1, 0.1, 1.0, 1.0, 1.0, 0.1]
DIFF_CHANNELS = len(DIFF_SCALE)


class Difference(nn.Module):
    """N x 7 x H x W: how each pixel's point, normal and depth changed since the reference."""

    def __init__(self):
        super().__init__()
        # Not persistent: a constant, and checkpoints stay loadable whatever its value.
        self.register_buffer("scale", torch.tensor(DIFF_SCALE).view(1, -1, 1, 1), persistent=False)

    def forward(self, cur: torch.Tensor, ref: torch.Tensor) -> torch.Tensor:
        d = torch.cat([cur[:, 0:3] - ref[:, 0:3], cur[:, 6:9] - ref[:, 6:9], cur[:, 9:10] - ref[:, 9:10]], dim=1)
        return d / self.scale


def mlp(cin: int, hidden: tuple[int, ...], cout: int) -> nn.Sequential:
    layers: list[nn.Module] = []
    for h in hidden:
        layers += [nn.Linear(cin, h), nn.ReLU(inplace=True)]
        cin = h
    return nn.Sequential(*layers, nn.Linear(cin, cout))


class ConvTower(nn.Module):
    """The paper's DirectionNet image encoder (its released model.py): a
    double convolution at full resolution, then one max-pool and double
    convolution per further width, flattened (the paper's 512 x 7 x 10 at
    480 x 640) into an MLP to `embedding` features. It sees the whole image,
    gripper included, not a grasp pixel."""

    def __init__(self, cin: int, widths: tuple[int, ...], embedding: int, height: int, width: int):
        super().__init__()
        stages: list[nn.Module] = [block(cin, widths[0])]
        for a, b in itertools.pairwise(widths):
            stages.append(nn.Sequential(nn.MaxPool2d(2), block(a, b)))
        self.stages = nn.Sequential(*stages)
        h, w = height >> (len(widths) - 1), width >> (len(widths) - 1)
        if h < 1 or w < 1:
            raise ValueError(
                f"paper_widths: {len(widths)} stages halve a {height}x{width} image below one pixel; give fewer widths"
            )
        self.features = mlp(widths[-1] * h * w, (embedding,), embedding)
        # He-normal convolutions, as the released code initialises them: with
        # PyTorch's default, seven stages shrink the signal ~10x each at init.
        for m in self.stages.modules():
            if isinstance(m, nn.Conv2d):
                nn.init.kaiming_normal_(m.weight)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.features(self.stages(x).flatten(1))


class DirectionEncoder(nn.Module):
    """Image embeddings at the grasp pixel for the Dist branch (current
    observation) and the AoT branch (current + reference observation).

    direction_net "context" (the default) also gives the AoT branch the
    current-minus-reference difference as explicit channels and both branches a
    global context vector; "plain" is the network of the models shipped before
    it (kept so their checkpoints still load); "paper" is the paper's
    (`ConvTower`): whole-image features, the same at every pixel."""

    def __init__(
        self, widths: tuple[int, ...], embedding: int, use_reference: bool = True, net: str = "context",
        fields: bool = False, image_size: tuple[int, int] = (96, 128),
        paper_widths: tuple[int, ...] = (32, 64, 128, 256, 512, 512, 512),
    ):  # fmt: skip
        super().__init__()
        self.use_reference = use_reference
        self.paper = net == "paper"
        if self.paper and fields:
            raise ValueError("--aux-fields reads a per-pixel embedding, which the paper's DirectionNet has not")
        # Auxiliary: the flow read linearly from the Dist branch's per-pixel
        # embedding, so the embedding the decoders see encodes how the part moves.
        self.flow_head = nn.Conv2d(embedding, 3, 1) if fields else None
        self.difference = Difference() if net == "context" and use_reference else None
        context = net == "context"
        self.norm1 = Normalize()
        self.norm2 = Normalize(2 if use_reference else 1)
        aot_in = CHANNELS * (2 if use_reference else 1) + (0 if self.difference is None else DIFF_CHANNELS)
        if self.paper:
            self.dist = ConvTower(CHANNELS, paper_widths, embedding, *image_size)
            self.aot = ConvTower(aot_in, paper_widths, embedding, *image_size)
        else:
            self.dist = UNet(CHANNELS, widths, embedding, context)
            self.aot = UNet(aot_in, widths, embedding, context)

    def maps(self, observation, reference):
        """Per-pixel embeddings (N x E x H x W) of the Dist and AoT branches."""
        cur = observation.permute(0, 3, 1, 2)
        dist_in = self.norm1(cur)
        if self.use_reference:
            ref = reference.permute(0, 3, 1, 2)
            aot_in = self.norm2(torch.cat([cur, ref], dim=1))
            if self.difference is not None:
                aot_in = torch.cat([aot_in, self.difference(cur, ref)], dim=1)
        else:
            aot_in = self.norm2(cur) + 0.0 * reference.sum()
        return self.dist(dist_in), self.aot(aot_in)

    def forward(self, observation, reference, pixel):
        dist_map, aot_map = self.maps(observation, reference)
        if self.paper:
            # Whole-image features; the pixel stays an input of the exported
            # graph (the package contract), contributing nothing.
            unused = 0.0 * pixel.sum().to(dist_map.dtype)
            return dist_map + unused, aot_map + unused
        return features_at(dist_map, pixel), features_at(aot_map, pixel)

    def forward_fields(self, observation, reference, pixel):
        """As `forward`, plus the flow predicted at every pixel (N x 3 x H x W)."""
        dist_map, aot_map = self.maps(observation, reference)
        return features_at(dist_map, pixel), features_at(aot_map, pixel), self.flow_head(dist_map)


class DirectionDecoder(nn.Module):
    """Scores one candidate direction from the cached image embeddings."""

    def __init__(
        self, embedding: int, action_embedding: int, variant: str = "umpnet", net: str = "context", hidden: int = 64
    ):
        super().__init__()
        self.variant = variant
        # "context": each output also gets a term linear in the direction, with
        # coefficients read from the embedding. An MLP over [embedding, action]
        # needs many units to approximate such a product, and "does this move
        # go along or against the part's displacement" is exactly one.
        self.bilinear_dist = nn.Linear(embedding, 3) if net == "context" else None
        self.bilinear_aot = nn.Linear(embedding, 3 * 3) if net == "context" else None
        # The paper's: an action MLP per branch (3 -> 128 -> 128 -> 128) and
        # 1024-1024-1024 decoders; the others share one action encoder.
        layers = 3 if net == "paper" else 1
        self.action = mlp(3, (action_embedding,) * (layers - 1 or 1), action_embedding)
        self.aot_action = mlp(3, (action_embedding,) * (layers - 1), action_embedding) if net == "paper" else None
        self.dist_head = mlp(embedding + action_embedding, (hidden,) * layers, 1)
        self.aot_head = mlp(embedding + action_embedding, (hidden,) * layers, 3)
        if variant == "inverse":
            self.inverse_head = nn.Sequential(nn.Linear(2 * embedding, hidden), nn.ReLU(), nn.Linear(hidden, 3))

    def forward(self, dist_embedding, aot_embedding, direction):
        """Returns (distance N, aot_logits N x 3); for signed-dist the distance is
        signed, for where2act it is the logit of "this action moves the object"."""
        a = self.action(direction)
        b = a if self.aot_action is None else self.aot_action(direction)
        distance = self.dist_head(torch.cat([dist_embedding, a], dim=1)).squeeze(1)
        aot_logits = self.aot_head(torch.cat([aot_embedding, b], dim=1))
        if self.bilinear_dist is not None:
            distance = distance + (self.bilinear_dist(dist_embedding) * direction).sum(dim=1)
            bil = self.bilinear_aot(aot_embedding).view(-1, 3, 3)
            aot_logits = aot_logits + (bil * direction[:, None, :]).sum(dim=2)
        return distance, aot_logits

    def inverse(self, dist_embedding, aot_embedding):
        """The Inverse baseline: the action direction, regressed from the current
        observation and the one to reach (not normalised)."""
        return self.inverse_head(torch.cat([dist_embedding, aot_embedding], dim=1))


def uses_reference(variant: str) -> bool:
    """Single-step models (SingleStep, the Where2Act-style binary model) see no reference."""
    return variant not in ("single-step", "where2act")


class UMPNet(nn.Module):
    def __init__(self, cfg):
        super().__init__()
        fields = getattr(cfg, "aux_fields", 0.0) > 0
        self.position = PositionNet(tuple(cfg.position_widths), fields)
        self.encoder = DirectionEncoder(
            tuple(cfg.direction_widths), cfg.embedding, uses_reference(cfg.variant), cfg.direction_net, fields,
            (cfg.height, cfg.width), tuple(getattr(cfg, "paper_widths", (32, 64, 128, 256, 512, 512, 512))),
        )  # fmt: skip
        self.decoder = DirectionDecoder(
            cfg.embedding, cfg.action_embedding, cfg.variant, cfg.direction_net, cfg.decoder_hidden
        )

    def direction(self, observation, reference, pixel, direction):
        de, ae = self.encoder(observation, reference, pixel)
        return self.decoder(de, ae, direction)

    def inverse(self, observation, target, pixel):
        de, ae = self.encoder(observation, target, pixel)
        return self.decoder.inverse(de, ae)
