"""Ricochet from Python: connect to a world, send it commands, read its frames as numpy
arrays.

```python
import ricochet

with ricochet.World.connect("tcp/127.0.0.1:7447", world="default") as world:
    world.send("fire_dye_pack", at=[50, 60])
    for frame in world.frames(120):
        print(frame.number, len(frame.particles), frame.bodies.pos[:3])
```

`docs/python.md` describes the whole of it.
"""

from .commands import COMMANDS
from .decode import FrameDecoder
from .errors import CommandRefused, ConnectionFailed, DecodeError, NoReply, RicochetError
from .frame import Bodies, Frame, Particles
from .world import Reply, World

__version__ = "0.1.0"

__all__ = [
    "COMMANDS",
    "Bodies",
    "CommandRefused",
    "ConnectionFailed",
    "DecodeError",
    "Frame",
    "FrameDecoder",
    "NoReply",
    "Particles",
    "Reply",
    "RicochetError",
    "World",
]
