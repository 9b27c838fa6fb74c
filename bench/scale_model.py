#!/usr/bin/env python3
"""A model of one Hessian product and of the setup at 1,000 and 10,000 ranks for Table 4's
configuration (cube-obstacle, hex8, H_s/h = 10, clusters of 4 x 4 x 4 subdomains), TFETI against
H-TFETI-DP, built from what this machine measures:

- per-subdomain compute: the committed Table 4 runs (bench/results/table4_late.json, 1 rank x 2
  threads): F, projector and setup seconds per subdomain and per application, the applications
  per Hessian product, and the coarse factor's nonzeros and set-up time against the coarse
  dimension (fitted as a power law over the four rows and extrapolated);
- MPI: bench/mpi_costs.cpp on 2 ranks of this machine (shared memory): allreduce and ping-pong
  latency and bandwidth. Many machines add a network; the model takes this machine's figures
  (a lower bound) and a latency that grows with log2(P) for the reductions.

Layout modelled: every rank holds one cluster of 64 subdomains (H-TFETI-DP: one cluster, TFETI:
64 clusters of one) on `--cores` cores. Per Hessian product: the F applications and projections
per product as measured; one forward and one reverse exchange per F with 26 neighbours (a rank's
block of 4 x 4 x 4 subdomains touches 26 others), each of a face's interface multipliers; per
projection one allreduce of the coarse vector (its length: the coarse dimension) and one solve
with the coarse factor replicated on every rank (2 x nonzeros x 8 bytes at the machine's triad
bandwidth); `--dots` dot products per product, each an allreduce of one partial sum per cluster
(the rank-independent sums of docs/method.md). Setup: the subdomain work per rank (assembly,
constraints, factorization: per-subdomain seconds x 64 / cores) and the coarse problem (forming
and factoring G~ G~^T: the largest TFETI row's coarse phase scaled by nonzeros^1.5).

Usage: bench/scale_model.py [--ranks 1000 10000] [--cores 4] [--dots 6] [--out scale_model.json]
(runs build/htfeti_mpi_costs and build/htfeti_stream; writes bench/results/OUT)."""
import argparse
import json
import math
import os
import subprocess

from common import ROOT, RESULTS, env, save


def fit_power(xs, ys):
    """y = a x^b by least squares in log-log."""
    lx = [math.log(x) for x in xs]
    ly = [math.log(y) for y in ys]
    n = len(xs)
    mx, my = sum(lx) / n, sum(ly) / n
    b = sum((u - mx) * (v - my) for u, v in zip(lx, ly)) / sum((u - mx) ** 2 for u in lx)
    return math.exp(my - b * mx), b


def mpi_costs():
    exe = os.path.join(ROOT, "build", "htfeti_mpi_costs")
    out = subprocess.run(["mpiexec", "-n", "2", "--bind-to", "core", exe], env=env(1), check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out)


def triad_gb_s():
    exe = os.path.join(ROOT, "build", "htfeti_stream")
    out = subprocess.run([exe, "256", "10"], env=env(1), check=True, capture_output=True,
                         text=True).stdout
    return json.loads(out)["triad_gb_s_median"]


def latency_bandwidth(rows):
    """alpha (s) from the smallest message, beta (bytes/s) from the largest."""
    small = min(rows, key=lambda r: r["doubles"])
    large = max(rows, key=lambda r: r["doubles"])
    alpha = small["seconds"]
    beta = 8.0 * large["doubles"] / max(large["seconds"] - alpha, 1e-12)
    return alpha, beta


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ranks", type=int, nargs="+", default=[1000, 10000])
    ap.add_argument("--cores", type=int, default=4)
    ap.add_argument("--dots", type=int, default=6)
    ap.add_argument("--table4", default=os.path.join(RESULTS, "table4_late.json"))
    ap.add_argument("--out", default="scale_model.json")
    a = ap.parse_args()
    runs = json.load(open(a.table4))["runs"]
    mpi = mpi_costs()
    bw = triad_gb_s() * 1e9
    ar_alpha, ar_beta = latency_bandwidth(mpi["allreduce"])
    pp_alpha, pp_beta = latency_bandwidth(mpi["ping_pong"])
    result = {"measured": {"mpi_2_ranks": mpi, "triad_gb_s": bw / 1e9,
                           "allreduce_alpha_s": ar_alpha, "allreduce_beta_bytes_s": ar_beta,
                           "p2p_alpha_s": pp_alpha, "p2p_beta_bytes_s": pp_beta},
              "assumptions": {"subdomains_per_rank": 64, "cores_per_rank": a.cores,
                              "neighbours": 26, "dots_per_product": a.dots}, "methods": {}}
    S = 64
    for method, m in [("TFETI", 1), ("H-TFETI-DP", 4)]:
        rows = sorted([r for r in runs if r["cluster_size"] == m], key=lambda r: r["subdomains"])
        big = rows[-1]
        th = big["threads"]
        per_sub = lambda seconds: seconds * th / big["subdomains"]  # core-seconds per subdomain
        f_per_app = per_sub(big["timings"]["F"]) / big["F_applications"]
        f_per_product = big["F_applications"] / big["matvecs"]
        proj_per_product = big["projector_applications"] / big["matvecs"]
        # A projection's own work (G~ and G~^T on the rank's multipliers), without the coarse
        # solve (2 x nonzeros x 8 bytes at the triad bandwidth, 2 threads).
        coarse_solve_big = 2.0 * big["memory"]["coarse_factor_nonzeros"] * 8.0 / bw
        proj_local = max(per_sub(big["timings"]["projector"] / big["projector_applications"]
                                 - coarse_solve_big), 0.0)
        # Setup per subdomain: assembly, constraints, factorization, cluster setup, and the coarse
        # phase's work counted as per-subdomain too (an upper bound: for TFETI it includes the
        # coarse factorization, modelled again below).
        setup_local = per_sub(sum(big["timings"][k] for k in
                                  ("assembly", "constraints", "factorization", "cluster_setup",
                                   "coarse_problem")))
        dims = [r["coarse_dimension"] for r in rows]
        nnz_a, nnz_b = fit_power(dims, [max(r["memory"]["coarse_factor_nonzeros"], 1) for r in rows])
        # The coarse factorization's time: the largest TFETI row's whole coarse phase (an upper
        # bound) scaled as nested dissection of a 3D graph, flops ~ nonzeros^1.5.
        tf = max((r for r in runs if r["cluster_size"] == 1), key=lambda r: r["subdomains"])
        factor_ref = (tf["timings"]["coarse_problem"], tf["memory"]["coarse_factor_nonzeros"])
        # Interface multipliers on one face of a rank's 4 x 4 x 4 block: (4 x 10 + 1)^2 nodes x 3.
        face_doubles = (4 * big["H_over_h"] + 1) ** 2 * 3
        per_rank = {}
        for P in a.ranks:
            coarse = 6 * S * P // (m ** 3)
            clusters = S * P // (m ** 3)
            nnz = nnz_a * coarse ** nnz_b
            log_p = math.log2(P)
            allreduce = lambda n: ar_alpha * log_p + 2.0 * 8.0 * n / ar_beta
            t_f = S * f_per_app / a.cores
            t_exchange = 2 * 26 * (pp_alpha + 8.0 * face_doubles / pp_beta)
            t_coarse_reduce = allreduce(coarse)
            t_coarse_solve = 2.0 * nnz * 8.0 / bw
            t_dots = a.dots * allreduce(clusters)
            product = {"F": f_per_product * t_f, "exchange": f_per_product * t_exchange,
                       "projection_local": proj_per_product * S * proj_local / a.cores,
                       "coarse_allreduce": proj_per_product * t_coarse_reduce,
                       "coarse_solve": proj_per_product * t_coarse_solve, "dots": t_dots}
            product["total"] = sum(product.values())
            setup = {"subdomains": S * setup_local / a.cores,
                     "coarse_factorization": factor_ref[0] * (nnz / factor_ref[1]) ** 1.5}
            setup["total"] = setup["subdomains"] + setup["coarse_factorization"]
            per_rank[str(P)] = {"coarse_dimension": coarse, "clusters": clusters,
                                "coarse_factor_nonzeros": nnz,
                                "coarse_factor_gb_per_rank": nnz * 12.0 / 1e9,
                                "product_seconds": product, "setup_seconds": setup,
                                "hessian_products_measured": big["matvecs"]}
        result["methods"][method] = {
            "from_row": {"subdomains": big["subdomains"], "coarse_dimension": big["coarse_dimension"]},
            "F_core_seconds_per_subdomain_application": f_per_app,
            "F_per_product": f_per_product, "projections_per_product": proj_per_product,
            "setup_core_seconds_per_subdomain": setup_local,
            "projection_local_core_seconds_per_subdomain": proj_local,
            "coarse_nonzeros_fit": [nnz_a, nnz_b],
            "ranks": per_rank}
        for P in a.ranks:
            r = per_rank[str(P)]
            p = r["product_seconds"]
            print(f"{method:10s} P={P:5d}: coarse {r['coarse_dimension']:8d}, factor "
                  f"{r['coarse_factor_gb_per_rank']:8.2f} GB/rank; product {p['total'] * 1e3:8.1f} ms "
                  f"(F {p['F'] * 1e3:.1f}, exchange {p['exchange'] * 1e3:.2f}, coarse allreduce "
                  f"{p['coarse_allreduce'] * 1e3:.2f}, coarse solve {p['coarse_solve'] * 1e3:.1f}, "
                  f"dots {p['dots'] * 1e3:.2f}, projection local {p['projection_local'] * 1e3:.1f}); "
                  f"setup {r['setup_seconds']['total']:.1f} s (coarse factorization "
                  f"{r['setup_seconds']['coarse_factorization']:.1f} s)")
    save(a.out, result)


if __name__ == "__main__":
    main()
