#!/bin/bash
# A Slurm job for htfeti (docs/user-guide.md, "Running on a cluster"): 4 machines, 2 ranks per
# machine (one per socket), 32 threads per rank. Submit with `sbatch docs/cluster/slurm-job.sh
# PROBLEM.toml`; the report and the VTU pieces go to the directory the job was submitted from.
#SBATCH --job-name=htfeti
#SBATCH --nodes=4
#SBATCH --ntasks-per-node=2
#SBATCH --cpus-per-task=32
#SBATCH --exclusive
#SBATCH --time=01:00:00
#SBATCH --output=htfeti-%j.out
set -euo pipefail
problem=${1:?usage: sbatch slurm-job.sh PROBLEM.toml}
# One OpenMP thread per core given to the rank; htfeti pins nothing itself.
export OMP_NUM_THREADS=${SLURM_CPUS_PER_TASK}
export OMP_PROC_BIND=close OMP_PLACES=cores
# --memory-limit (GB per machine) when the job may not use the whole machine; the memory check
# sums its estimate over the ranks of each machine and stops every rank with exit 2 before the
# setup when it does not fit. For a mesh too large for one machine give it as Gmsh's parts
# (`[mesh] parts = "NAME.msh"`, one file per part): every rank then reads only its own, and
# `srun ... htfeti solve "$problem" --dry-run` prints what each rank holds before anything runs.
# --coarse-ranks: one copy of the coarse factor per machine instead of one per rank (srun places
# the ranks machine by machine, so the groups of consecutive ranks are the machines).
srun --cpu-bind=cores htfeti solve "$problem" --coarse-ranks "${SLURM_JOB_NUM_NODES}" \
  --report "htfeti-${SLURM_JOB_ID}.json" --vtu "htfeti-${SLURM_JOB_ID}.pvtu" --progress
