#!/usr/bin/env bash
# Slurm's cost per job (docs/slurm.md): starts a single-node cluster with
# tests/slurm/cluster.sh in a temporary folder, runs bench_slurm_overhead
# (independent jobs, one array, a chain), stops the cluster.
#   bench/slurm_overhead.sh BUILD_DIR [N [SECONDS]]
set -u
here=$(cd "$(dirname "$0")/.." && pwd)
build=${1:?usage: slurm_overhead.sh BUILD_DIR [N [SECONDS]]}
n=${2:-20}
seconds=${3:-0}
dir=$(mktemp -d /tmp/sl-slurm-bench.XXXXXX)
chmod 755 "$dir"
trap 'bash "$here/tests/slurm/cluster.sh" stop "$dir/cluster"; rm -rf "$dir"' EXIT
bash "$here/tests/slurm/cluster.sh" start "$dir/cluster" >/dev/null || exit 1
read -r total _ munge _ daemons _ node <"$dir/cluster/run/start_seconds"
echo "cluster up in $total s (munged $munge s, slurmctld + slurmd $daemons s, node idle $node s)"
export SLURM_CONF="$dir/cluster/slurm.conf"
"$build/bench/bench_slurm_overhead" "$n" "$seconds" 2 "$dir/jobs"
