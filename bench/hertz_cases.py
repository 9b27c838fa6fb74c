"""The graded Hertz blocks of issue 32, shared by bench/graded_hertz.py and
bench/refinement_continuation.py: the gmsh inputs (MESHES: label, .geo file, gmsh arguments)
and the problem file text (COMMON with {msh} to fill, CONTACT: the rigid sphere)."""

MESHES = [
    ("hex8, strong grading (hmin 0.005)", "graded_block_hex.geo", ["-setnumber", "hmin", "0.005"]),
    ("hex8, mild grading (hmin 0.015)", "graded_block_hex.geo", ["-setnumber", "hmin", "0.015"]),
    ("hex8, uniform (1/32)", "graded_block_hex.geo", ["-setnumber", "hmin", "0.03125"]),
    ("tet4, size field (0.004 to 0.07)", "graded_block_tet.geo",
     ["-setnumber", "h", "0.004", "-setnumber", "H", "0.07"]),
]
COMMON = """[mesh]
file = "{msh}"
[physics]
type = "elasticity"
young = 1000.0
poisson = 0.3
[[dirichlet]]
group = "bottom"
[[dirichlet]]
group = "x0"
components = ["x"]
[[dirichlet]]
group = "y0"
components = ["y"]
[decomposition]
subdomains = 16
[solver]
rtol = 1e-4
"""
CONTACT = """[[contact]]
group = "top"
direction = [0.0, 0.0, 1.0]
gap = "0.99 - sqrt(max(1e-12, 1 - x^2 - y^2))"
"""


def contact_problems(tmp):
    """Meshes every block of MESHES with gmsh into the directory tmp and writes its contact
    problem file there: a list of ("Hertz " + label, problem file path)."""
    import os
    import subprocess
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    out = []
    for i, (label, geo, args) in enumerate(MESHES):
        msh = os.path.join(tmp, f"hertz{i}.msh")
        subprocess.run(["gmsh", os.path.join(root, "bench", geo), "-3", *args, "-format", "msh41",
                        "-o", msh], check=True, stdout=subprocess.DEVNULL)
        toml = os.path.join(tmp, f"hertz{i}.toml")
        with open(toml, "w") as f:
            f.write(COMMON.format(msh=msh) + CONTACT)
        out.append(("Hertz " + label, toml))
    return out
