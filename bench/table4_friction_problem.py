"""The cube-obstacle of Table 4 with an optional friction line, shared by
bench/table4_friction.py and bench/smalbe_sweep.py --friction: fill n (elements per side),
s (subdomains per side), m (cluster size) and friction (a `friction = {...}` line or "")."""

PROBLEM = """[mesh]
generator = "box"
size = [100.0, 100.0, 100.0]
elements = [{n}, {n}, {n}]
element = "hex8"
[physics]
type = "elasticity"
young = 2.1e7
poisson = 0.3
density = 7850.0
gravity = [0.0, 0.0, -9.8066]
[[dirichlet]]
group = "x0"
[[contact]]
group = "z0"
direction = [0.0, 0.0, -1.0]
gap = "sin(pi*x/50)"
{friction}
[decomposition]
subdomains = [{s}, {s}, {s}]
cluster_size = {m}
[solver]
preconditioner = "none"
"""
