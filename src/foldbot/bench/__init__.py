"""Benchmarks: suite files → episodes (local processes or Ray) → summary, table and plot.

- `suite`: load and validate a suite file (suites/NAME.toml) into episode specs with stable ids.
- `runner`: run the missing episodes, one fresh process each, locally or on a Ray cluster.
- `summary`: the field's metrics per group (garment × recipe × perception × loop) and overall.
- `report`: summary.json, summary.md and errors.png, each written atomically.
- `ravens_reference`: the same towel in plain PyBullet at Deformable Ravens' settings, for speed.
"""
