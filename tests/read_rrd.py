#!/usr/bin/env python3
"""Summarises a viewer's .rrd file as JSON, for tests/viewer.rs.

    python3 tests/read_rrd.py FILE.rrd

Reads the file with the `rerun` package (rerun-sdk==0.36.3) and prints:
- entities: per entity path, whether all its data is static, the `frame` values it was
  logged at, and (line strips) the number of strips per row;
- particle_counts / particle_figures: per frame, the points of /world/particles and the
  value of /stats/particles;
- stats_frames: how many frames have figures (/stats/step_ms);
- events: the lines of the text log /events;
- scalars: per entity under /drift/ (the plots of how far worlds drift apart), its value
  at each frame;
- translations: per entity with a transform (a world's root, side by side), its x, y, z;
- labels: per entity with labelled points (a world's name), the labels.
"""
import json
import sys

from rerun.experimental import RrdReader


def main(path):
    entities = {}
    particle_counts, particle_figures, events = {}, {}, []
    stats_frames = set()
    scalars, translations, labels = {}, {}, {}
    for chunk in RrdReader(path).stream().to_chunks():
        ent = chunk.entity_path
        batch = chunk.to_record_batch()
        names = batch.schema.names
        info = entities.setdefault(ent, {"static": True, "frames": set(), "strips": []})
        info["static"] = info["static"] and chunk.is_static
        frames = batch.column("frame").to_pylist() if "frame" in names else [None] * batch.num_rows
        info["frames"].update(f for f in frames if f is not None)
        if "LineStrips2D:strips" in names:
            for row in batch.column("LineStrips2D:strips").to_pylist():
                if row is not None:
                    info["strips"].append(len(row))
        if ent == "/world/particles" and "Points2D:positions" in names:
            for f, row in zip(frames, batch.column("Points2D:positions").to_pylist()):
                if row is not None:
                    particle_counts[str(f)] = len(row)
        if ent == "/stats/particles" and "Scalars:scalars" in names:
            for f, row in zip(frames, batch.column("Scalars:scalars").to_pylist()):
                if row:
                    particle_figures[str(f)] = row[0]
        if ent.startswith("/drift/") and "Scalars:scalars" in names:
            values = scalars.setdefault(ent, {})
            for f, row in zip(frames, batch.column("Scalars:scalars").to_pylist()):
                if row:
                    values[str(f)] = row[0]
        if "Transform3D:translation" in names:
            for row in batch.column("Transform3D:translation").to_pylist():
                if row is not None:
                    translations[ent] = row[0] if isinstance(row[0], list) else row
        if "Points2D:labels" in names:
            for row in batch.column("Points2D:labels").to_pylist():
                if row:
                    labels[ent] = row
        if ent == "/stats/step_ms":
            stats_frames.update(f for f in frames if f is not None)
        if ent == "/events" and "TextLog:text" in names:
            for f, row in zip(frames, batch.column("TextLog:text").to_pylist()):
                if row:
                    events.extend(row)
    for info in entities.values():
        info["frames"] = sorted(info["frames"])
    json.dump(
        {
            "entities": entities,
            "particle_counts": particle_counts,
            "particle_figures": particle_figures,
            "stats_frames": len(stats_frames),
            "events": events,
            "scalars": scalars,
            "translations": translations,
            "labels": labels,
        },
        sys.stdout,
    )


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: read_rrd.py FILE.rrd")
    main(sys.argv[1])
