"""Reads a gelrig Parquet export with pandas (pyarrow) and prints, as JSON, each table's row
count, column dtypes, the `unit` metadata of each field and, where there is a `run` column,
its categories. Used by tests/e2e/export.rs."""
import json, pathlib, sys

import pandas as pd
import pyarrow.parquet as pq

out = {}
for f in sorted(pathlib.Path(sys.argv[1]).glob("*.parquet")):
    df = pd.read_parquet(f)
    schema = pq.read_schema(f)
    units = {fld.name: fld.metadata[b"unit"].decode()
             for fld in schema if fld.metadata and b"unit" in fld.metadata}
    t = {"rows": len(df), "dtypes": {c: str(d) for c, d in df.dtypes.items()}, "units": units}
    if "run" in df:
        t["runs"] = sorted(str(c) for c in df["run"].unique())
    out[f.stem] = t
print(json.dumps(out))
