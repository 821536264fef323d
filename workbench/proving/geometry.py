"""Geometry errors of the proving ground's articles: the frame as built is not quite where its file says.

A frame file's coordinates are what an engineer measured with a rule or a tape: each end of a member (a
corner, a foot) sits off its nominal place by about a millimetre in each direction (`NuisanceSettings`,
``geometry_sd``), independently, so that each member comes out a little longer or shorter and a little
tilted, each by its own amount (not the same stretch everywhere, which a model error of one common factor
would absorb). Everything placed *along* a member keeps its fraction of the member's length: a point on it (a
sensor, the drive), a joint's span, an effect's zone, hinge or anchor; a part off the frame (a shaker
armature's node) stays where it was. A rod's misfit is its stress-free length minus the distance between its
anchors (`workbench.proving.article.Rod`), so a prestress stays the one the mechanism set.

The draws come after every other draw of the article stream, so that a case's materials, sections, damping
and sensors are the same with the geometry error on or off (`workbench.proving.campaigns`).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from workbench.model.frame import member_ends, moved_frame
from workbench.proving.article import Anchor, Article

__all__ = ["moved_article", "perturb_geometry"]


def _anchor(anchor: Anchor, ratio: dict[str, float]) -> Anchor:
    if isinstance(anchor, tuple):
        return (anchor[0], anchor[1] * ratio[anchor[0]])
    return anchor


def moved_article(article: Article, offsets: dict[str, tuple[float, float]]) -> Article:
    """``article`` with its member ends moved by ``offsets`` (m; module docstring)."""
    moved, ratio = moved_frame(article.frame, offsets)
    return replace(
        article, frame=moved,
        zones=tuple(replace(z, span=(z.span[0] * ratio[z.member], z.span[1] * ratio[z.member])) for z in article.zones),
        hinges=tuple(replace(h, station=h.station * ratio[h.member]) for h in article.hinges),
        rods=tuple(replace(r, start=_anchor(r.start, ratio), end=_anchor(r.end, ratio)) for r in article.rods),
        attachments=tuple(replace(a, anchor=_anchor(a.anchor, ratio)) for a in article.attachments),
        dashpots=tuple(replace(d, a=_anchor(d.a, ratio), b=_anchor(d.b, ratio)) for d in article.dashpots),
        excitation=None if article.excitation is None else (_anchor(article.excitation[0], ratio),
                                                            article.excitation[1]),
    )


def perturb_geometry(article: Article, geometry_sd: float, rng: np.random.Generator) -> tuple[Article, dict[str, Any]]:
    """The article with each member end off by ``geometry_sd`` (m) in x and in y, and the record of the offsets."""
    ends = member_ends(article.frame)
    draws = geometry_sd * rng.standard_normal((len(ends), 2))
    offsets = {n: (float(dx), float(dy)) for n, (dx, dy) in zip(ends, draws)}
    return moved_article(article, offsets), {"point_offsets_m": {n: list(v) for n, v in offsets.items()}}
