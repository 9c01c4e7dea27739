"""The simulated cell: PyBullet world, table, robots, soft-body cloth, RGB-D camera, ground-truth oracle."""
