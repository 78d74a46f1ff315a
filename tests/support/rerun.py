"""Reading Rerun recordings back in the tests with Rerun's own reader (``rerun.chunk.RrdReader``), independent of
psvs's writer."""
import numpy as np

#: Rerun's channel datatypes (ChannelDatatype) the tests meet: U8 and F32.
DTYPES = {6: np.uint8, 34: np.float32}


def read_rrd(path) -> dict:
    """{entity path: [row {component column: value}]} of an .rrd file, rows in time order (static rows first);
    ``time`` in s (None on a static row)."""
    import pyarrow as pa
    from rerun.chunk import RrdReader
    out: dict = {}
    for chunk in RrdReader(str(path)).stream().to_chunks():
        b = chunk.to_record_batch()
        cols = {n: (b.column(n).cast(pa.int64()).to_pylist() if n == "time" else b.column(n).to_pylist())
                for n in b.schema.names if n == "time" or ":" in n}
        for k in range(b.num_rows):
            row = {n: v[k] for n, v in cols.items()}
            row["time"] = None if row.get("time") is None else row["time"] * 1e-9
            out.setdefault(chunk.entity_path, []).append(row)
    for rows in out.values():
        rows.sort(key=lambda r: -1.0 if r["time"] is None else r["time"])
    return out


def image_of(row: dict, archetype: str = "Image") -> np.ndarray:
    """The (H, W) array of an Image or DepthImage row."""
    fmt = row[f"{archetype}:format"][0]
    return np.frombuffer(bytes(row[f"{archetype}:buffer"][0]), DTYPES[fmt["channel_datatype"]]).reshape(
        fmt["height"], fmt["width"])
