"""The contact problems of bench/smalbe_sweep.py and bench/contact_products.py: a list of
(name, htfeti solve arguments). The base cases (Table 3 reduced, Table 4's 1 x 1 x 1, the
membrane examples, the cube-obstacle at A = 20 and at rtol 1e-10, the plate with a hole), and
with metis the 40^3 cube split by METIS (two objectives, clusters of 8) and the contact examples,
with hertz the four graded Hertz blocks (bench/hertz_cases.py, needs gmsh), with friction the
friction examples and Table 4's cube with Coulomb friction (TFETI and H-TFETI-DP). Generated files
go to the directory tmp."""
import os

from common import ROOT
from hertz_cases import contact_problems
from table4_friction_problem import PROBLEM as FRICTION_CUBE


def example(name):
    return os.path.join(ROOT, "examples", name + ".toml")


def case_file(name):
    return os.path.join(ROOT, "bench", "cases", name + ".toml")


def contact_cases(tmp, metis=False, hertz=False, friction=False, tight=True):
    """tight: also the cube-obstacle 10 x 20 x 10 at rtol 1e-10 (its own rtol)."""
    cases = [(f"Table 3 reduced m = {m}",
              ["--problem", "membranes", "-n", 512, "--subdomains", 32, "-m", m])
             for m in (1, 2, 4, 8)]
    cases += [("Table 4 1x1x1 TFETI", ["--problem", "cube-obstacle", "--elements", 40,
                                       "--subdomains", 4, "--cluster-size", 1,
                                       "--preconditioner", "none"]),
              ("Table 4 1x1x1 H-TFETI-DP", ["--problem", "cube-obstacle", "--elements", 40,
                                            "--subdomains", 4, "--cluster-size", 4,
                                            "--preconditioner", "none"]),
              ("example membranes", [example("membranes")]),
              ("example membranes-coercive", [example("membranes-coercive")]),
              ("cube-obstacle amplitude 20", ["--problem", "cube-obstacle",
                                              "--obstacle-amplitude", 20])]
    if tight:
        cases += [("cube-obstacle 10x20x10 rtol 1e-10",
                   ["--problem", "cube-obstacle", "--elements", "10,20,10", "--subdomains",
                    "2,4,2", "--rtol", 1e-10])]
    cases += [("plate hole inactive contact rtol 1e-6", [case_file("plate_hole_inactive_contact")])]
    if metis:
        cases += [(f"cube-obstacle 40^3 METIS 64 ({o})",
                   [case_file("cube40_metis64"), "--partition-objective", o])
                  for o in ("volume", "cut")]
        cases += [("cube-obstacle 40^3 METIS 64, clusters of 8 (H-TFETI-DP)",
                   [case_file("cube40_metis64"), "--cluster-size", 8])]
        cases += [(f"example {n}", [example(n)])
                  for n in ("cylinder-on-block", "sphere-on-block", "punch-on-block")]
    if hertz:
        cases += [(name, [path]) for name, path in contact_problems(tmp)]
    if friction:
        cases += [(f"example {n}", [example(n)]) for n in ("friction-block", "friction-block-3d")]
        for method, m in (("TFETI", 1), ("H-TFETI-DP", 4)):
            path = os.path.join(tmp, f"coulomb{m}.toml")
            with open(path, "w") as f:
                f.write(FRICTION_CUBE.format(n=40, s=4, m=m, friction=(
                    'friction = { law = "coulomb", coefficient = 0.3 }')))
            cases += [(f"Table 4 1x1x1 {method}, Coulomb mu = 0.3", [path])]
    return cases
