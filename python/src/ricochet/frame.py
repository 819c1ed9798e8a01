"""A decoded frame: its bodies and particles as numpy column arrays."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt


@dataclass(frozen=True)
class Bodies:
    """The dynamic bodies of a frame, by increasing key: row `i` of every array is the
    body `ids[i]`."""

    ids: list[str]
    """Each body's id, as the scene or the command that made it names it."""
    groups: list[str]
    pos: npt.NDArray[np.float64]
    """Positions, shape (n, 2), units; within 1/2048 of the server's on each axis."""
    vel: npt.NDArray[np.float64]
    """Velocities, shape (n, 2), units per second: the displacement over the last frame
    over that frame's time."""
    size: npt.NDArray[np.float32]
    """Width and height, shape (n, 2) (a circle: its diameter twice)."""
    circle: npt.NDArray[np.bool_]
    collided: npt.NDArray[np.bool_]

    def __len__(self) -> int:
        return len(self.ids)

    def index(self, body_id: str) -> int:
        """The row of the body `body_id`; ValueError when the frame has no such body."""
        try:
            return self.ids.index(body_id)
        except ValueError:
            raise ValueError(f"no dynamic body {body_id!r} in this frame") from None


@dataclass(frozen=True)
class Particles:
    """The particles of a frame, by increasing id."""

    ids: npt.NDArray[np.uint32]
    pos: npt.NDArray[np.float32]
    """Positions, shape (n, 2); within 1/512 units of the server's on each axis."""
    vel: npt.NDArray[np.float32]
    """Velocities, shape (n, 2), units per second."""
    size: npt.NDArray[np.float32]
    color: npt.NDArray[np.float32]
    """Colours, shape (n, 4): red, green, blue, alpha (a component may exceed 1: the fire
    preset's red reaches 4.5)."""

    def __len__(self) -> int:
        return len(self.ids)


@dataclass(frozen=True)
class Frame:
    """One frame of a world, as a receiver holds it after applying it."""

    number: int
    """Steps the world has taken."""
    time: float
    """Simulated seconds."""
    dt: float
    """The world's step, seconds."""
    bodies: Bodies
    particles: Particles
    statics: int
    """How many static bodies the latest snapshot holds."""
    emitters: npt.NDArray[np.float64]
    """Emitters, shape (m, 3): x, y and the particles each still has to release."""
    stats: dict[str, float] = field(default_factory=dict)
    """The step's figures: step_ms, contacts, solver_passes, deepest_penetration,
    kinetic_energy, particle_contacts, overruns, dynamic_bodies, particles, emitters,
    energy_change, residual."""

    def plain(self) -> dict[str, Any]:
        """The frame as plain data (lists and dicts): what `ricochet_client.py watch`
        prints, a line of JSON a frame."""
        b, p = self.bodies, self.particles
        return {
            "frame": self.number,
            "t": self.time,
            "bodies": [
                {"id": i, "x": x, "y": y, "vx": vx, "vy": vy, "collided": c}
                for i, (x, y), (vx, vy), c in zip(b.ids, b.pos.tolist(), b.vel.tolist(), b.collided.tolist())
            ],
            "statics": self.statics,
            "particles": [
                {"x": x, "y": y, "size": s, "color": c}
                for (x, y), s, c in zip(p.pos.tolist(), p.size.tolist(), p.color.tolist())
            ],
            "emitters": len(self.emitters),
            "stats": self.stats,
        }
