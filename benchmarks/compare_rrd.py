"""Check that two recordings hold the same entities and the same transforms at every frame (bench_all.py --verify:
urdf-pipeline's output against the hand-written one). Slow above ~100k frames (frame names go through Python lists).
Usage: python benchmarks/compare_rrd.py A.rrd B.rrd   (prints one line; exit 1 when they differ)
"""

from __future__ import annotations

import sys
from pathlib import Path


def transform_tables(path: Path) -> tuple[dict, set]:
    import numpy as np
    import pyarrow.compute as pc
    from rerun.chunk import RrdReader

    parts: dict[str, list] = {}
    layout: set = set()
    for chunk in RrdReader(path).stream().to_chunks():
        batch = chunk.to_record_batch()
        layout.add((chunk.entity_path, chunk.is_static, tuple(sorted(n for n in batch.schema.names if ":" in n))))
        if "Transform3D:child_frame" not in batch.schema.names:
            continue
        flat = {
            n: pc.list_flatten(batch.column(n))
            for n in ("Transform3D:translation", "Transform3D:quaternion", "Transform3D:parent_frame", "Transform3D:child_frame")
        }
        frame = batch.column("frame_index").to_numpy() if "frame_index" in batch.schema.names else np.full(batch.num_rows, -1)
        parts.setdefault(chunk.entity_path, []).append(
            (
                frame,
                np.asarray(flat["Transform3D:child_frame"].to_pylist()),
                np.asarray(flat["Transform3D:parent_frame"].to_pylist()),
                pc.list_flatten(flat["Transform3D:translation"]).to_numpy().reshape(-1, 3),
                pc.list_flatten(flat["Transform3D:quaternion"]).to_numpy().reshape(-1, 4),
            )
        )
    tables = {}
    for entity, chunks in parts.items():
        frame, child, parent, translation, quaternion = (np.concatenate(c) for c in zip(*chunks, strict=True))
        order = np.lexsort((child, frame))
        tables[entity] = (frame[order], child[order], parent[order], translation[order], quaternion[order])
    return tables, layout


def verify(a: Path, b: Path) -> str:
    import numpy as np

    ta, la = transform_tables(a)
    tb, lb = transform_tables(b)
    entities = lambda layout: {(e, s, c) for e, s, c in layout if not e.startswith("/__")}  # noqa: E731
    if {e for e, _, _ in entities(la)} != {e for e, _, _ in entities(lb)}:
        return f"DIFFERENT entities: {sorted({e for e, _, _ in entities(la)} ^ {e for e, _, _ in entities(lb)})}"
    if set(ta) != set(tb):
        return f"DIFFERENT transform entities: {sorted(ta)} vs {sorted(tb)}"
    worst = 0.0
    for entity in ta:
        (fa, ca, pa_, xa, qa), (fb, cb, pb, xb, qb) = ta[entity], tb[entity]
        if not (np.array_equal(fa, fb) and np.array_equal(ca, cb) and np.array_equal(pa_, pb)):
            return f"DIFFERENT frames/edges in {entity}"
        worst = max(worst, float(np.abs(xa - xb).max(initial=0)), float(np.abs(qa - qb).max(initial=0)))
    rows = {e: len(t[0]) for e, t in ta.items()}
    return f"same entities and transforms (max abs difference {worst:.3g}); transform rows {rows}"


if __name__ == "__main__":
    result = verify(Path(sys.argv[1]), Path(sys.argv[2]))
    print(result)
    raise SystemExit(0 if result.startswith("same") else 1)
