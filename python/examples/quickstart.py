"""Connect to a running world, strike a body, watch 120 frames as numpy arrays.

    ricochet-server run --scene assets/scenes/emitters.toml &
    python3 python/examples/quickstart.py tcp/127.0.0.1:7447
"""
import sys

import numpy as np

import ricochet

endpoint = sys.argv[1] if len(sys.argv) > 1 else "tcp/127.0.0.1:7447"
with ricochet.World.connect(endpoint, world="default") as world:
    world.resume()
    ball = world.spawn(body={"id": "ball", "shape": "circle", "radius": 2, "pos": [30, 60], "mass": 1})
    world.impulse(ball, [40, 0])  # strike it: +40 units/s along x
    frames = list(world.frames(120))
    path = np.array([f.bodies.pos[f.bodies.index(ball)] for f in frames])
    print(f"{len(frames)} frames, {frames[0].number} to {frames[-1].number}")
    print(f"ball moved {path[-1, 0] - path[0, 0]:+.2f} units along x")
    print(f"up to {max(len(f.particles) for f in frames)} particles a frame")
