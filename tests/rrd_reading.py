"""Reading .rrd recordings back in the tests (rerun's chunk reader): not a test module."""

import numpy as np
from rerun.chunk import RrdReader


def read_rrd(path):
    """entity path -> {'static': [record batches], 'temporal': [record batches]}."""
    out = {}
    for chunk in RrdReader(path).stream().to_chunks():
        d = out.setdefault(chunk.entity_path, {"static": [], "temporal": []})
        d["static" if chunk.is_static else "temporal"].append(chunk.to_record_batch())
    return out


def column(batches, name, index=None):
    """Concatenate a component column over batches, sorted by ``index`` when given."""
    vals, idx = [], []
    for b in batches:
        if name in b.schema.names:
            vals += b.column(name).to_pylist()
            if index:
                idx += b.column(index).to_pylist()
    if index:
        order = np.argsort(idx, kind="stable")
        return [vals[i] for i in order], np.asarray(idx)[order]
    return vals
