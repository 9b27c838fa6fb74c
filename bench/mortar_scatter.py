#!/usr/bin/env python3
"""The scatter of the mortar multipliers on the 3D Cattaneo-Mindlin sphere (the h = 0.01 level of
bench/cattaneo_mindlin.py --dim 3: tet4, the block's top as the slave, Coulomb mu = 0.3) with the
dual and the standard multiplier spaces (`multipliers` of the contact pair): the nodal pressures
within 0.8 a of the axis against Hertz's profile p0 (1 - r^2 / a^2)^(1/2) (rms, min and max of
p / p_Hertz - 1, P measured), the range of the tangential tractions of the stick nodes within
r = 0.03 (Mindlin: 2.3-2.6 there), the stick radius error and the Hessian products. --tight
adds the standard space at rtol 1e-11 (the scatter is the discrete solution's, not the
solver's).

Usage: bench/mortar_scatter.py [--tight] [--out mortar_scatter.json]   (needs the gmsh program)
Writes bench/results/OUT."""
import argparse
import math
import os
import subprocess
import tempfile

from cattaneo_mindlin import CONDITIONS, E, E_STAR, MU, NU, PROBLEM, radius_3d
from common import ROOT, save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--tight", action="store_true")
p.add_argument("--out", default="mortar_scatter.json")
a = p.parse_args()
runs = [("dual", "1e-8"), ("standard", "1e-8")] + ([("standard", "1e-11")] if a.tight else [])
rows = []
with tempfile.TemporaryDirectory() as tmp:
    msh = os.path.join(tmp, "m.msh")
    subprocess.run(["gmsh", os.path.join(ROOT, "examples", "meshes", "sphere-on-block.geo"), "-3",
                    "-setnumber", "half", "1", "-setnumber", "h", "0.01", "-format", "msh41",
                    "-o", msh], check=True, stdout=subprocess.DEVNULL)
    for space, rtol in runs:
        text = PROBLEM.format(mesh=msh, E=E, NU=NU, MU=MU, conditions=CONDITIONS[3].format(
            side=0.0012, down=-0.006)).replace("rtol = 1e-8", f"rtol = {rtol}")
        text = text.replace('master = "sphere_surface"',
                            f'master = "sphere_surface"\nmultipliers = "{space}"')
        toml = os.path.join(tmp, f"{space}-{rtol}.toml")
        with open(toml, "w") as f:
            f.write(text)
        r = solve([toml], threads=2)
        s, c = r["contact_summary"][0], r["contact"]
        P, Q = 2 * abs(s["resultant"][2]), 2 * abs(s["tangential_force"][0])
        radius = (3 * P / (4 * E_STAR)) ** (1 / 3)
        p0 = 3 * P / (2 * math.pi * radius ** 2)
        dev, stick_t = [], []
        for x, y, pr, t, st in zip(c["x"], c["y"], c["pressure"], c["tangential_traction"],
                                   c["state"]):
            if st is None:
                continue
            rr = math.hypot(x, y)
            if rr < 0.8 * radius:
                dev.append(pr / (p0 * math.sqrt(1 - rr * rr / radius ** 2)) - 1)
            if st == 1 and rr < 0.03:
                stick_t.append(t)
        theory = radius * max(0.0, 1 - Q / (MU * P)) ** (1 / 3)
        stick, _, _ = radius_3d(c)
        row = {"multipliers": space, "rtol": float(rtol), "nodes": len(dev),
               "pressure_rms": math.sqrt(sum(d * d for d in dev) / len(dev)),
               "pressure_min": min(dev), "pressure_max": max(dev), "stick_nodes_r003": len(stick_t),
               "stick_traction_min": min(stick_t), "stick_traction_max": max(stick_t),
               "stick_radius_error": stick / theory - 1, "products": r["matvecs"]}
        rows.append(row)
        print(f"{space:8s} rtol {rtol:6s}: pressure - Hertz {100 * row['pressure_rms']:.1f}% rms "
              f"({100 * row['pressure_min']:+.0f}% to {100 * row['pressure_max']:+.0f}%), "
              f"stick tractions r < 0.03: {row['stick_traction_min']:.2f} to "
              f"{row['stick_traction_max']:.2f} ({len(stick_t)} nodes), stick radius "
              f"{100 * row['stick_radius_error']:+.1f}%, {row['products']} products", flush=True)
print(save(a.out, {"command": "bench/mortar_scatter.py" + (" --tight" if a.tight else ""),
                   "rows": rows}))
