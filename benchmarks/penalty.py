"""The quadratic penalty baseline: a scene's contact as a penalty instead of IPC's barrier.

Everything else is the real solver: the same integrator, elasticity (with its inversion
bound), projected Newton and line search, candidate sets and statistics. Only the contact
terms change, chosen the way any scene chooses them (``contact.formulation = "penalty"``,
see ``ipcsim/potentials/terms.py``), and with them the CCD filter disappears.

The stiffness is given as a multiple c of W/d̂, W the weight of the heaviest simulated
body: k = c·W/d̂ is the spring that holds that body up with a penetration of d̂/c when a
single pair carries it. c = 1e3 is soft (a resting body sinks visibly into the d̂ band under
impacts), 1e7 is stiff (the linear systems get ill conditioned and Newton needs many
iterations); 1e5 is in between.
"""

from __future__ import annotations

from pathlib import Path

import msgspec
import numpy as np

from ipcsim.model.build import build_model
from ipcsim.model.model import GRAVITY
from ipcsim.scene import load_scene, save_scene

STIFFNESS_FACTORS = (1e3, 1e5, 1e7)


def heaviest_weight(model) -> float:
    """W = m g of the heaviest body with tets (kinematic vertices excluded)."""
    moving = ~np.asarray(model.always_kinematic, dtype=bool)
    shapes = np.asarray(model.vertex_shape)[moving]
    masses = np.bincount(shapes, weights=np.asarray(model.mass)[moving])
    return float(masses.max() * np.linalg.norm(GRAVITY))


def penalty_stiffness(model, factor: float) -> float:
    """k = c · W / d̂ (N/m per contact pair)."""
    return factor * heaviest_weight(model) / model.dhat


def penalty_scene(scene: Path, factor: float) -> Path:
    """Write ``scene`` with penalty contact of stiffness c·W/d̂ beside it (a .toml named
    after c) and return its path."""
    spec = load_scene(scene)
    k = penalty_stiffness(build_model(spec), factor)
    spec = msgspec.structs.replace(spec, contact_formulation="penalty", penalty_stiffness=k)
    return save_scene(spec, scene.with_name(f"{scene.stem}_penalty_{factor:.0e}.toml"))
