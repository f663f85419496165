#!/usr/bin/env bash
# A local stand-in for sbatch, for Snakemake's cluster-generic executor (tests/test_cluster.py):
#
#   snakemake --executor cluster-generic \
#     --cluster-generic-submit-cmd "tests/cluster_submit.sh --name {name} --mem {resources.mem_mb} --time {resources.runtime} --cpus {threads}"
#
# Snakemake appends the job script path.  Like a batch scheduler, the job script is started
# detached (new session, no terminal, own log file) and the script returns at once, printing a job
# id.  Snakemake then learns the job's fate only from the jobfinished/jobfailed marker files the
# job script writes.  Each submission is appended to $CLUSTER_SUBMIT_LOG (tab-separated: job id,
# pid, name, mem_mb, runtime, cpus, job script).
set -euo pipefail
name=job mem=NA runtime=NA cpus=NA
while [ $# -gt 1 ]; do
  case "$1" in
    --name) name=$2; shift 2 ;;
    --mem) mem=$2; shift 2 ;;
    --time) runtime=$2; shift 2 ;;
    --cpus) cpus=$2; shift 2 ;;
    *) echo "cluster_submit.sh: unknown option '$1' (use --name, --mem, --time, --cpus)" >&2; exit 2 ;;
  esac
done
jobscript=${1:?"cluster_submit.sh: no job script given"}
[ -r "$jobscript" ] || { echo "cluster_submit.sh: job script '$jobscript' not readable" >&2; exit 2; }
logdir=${CLUSTER_LOG_DIR:-cluster_logs}
mkdir -p "$logdir"
id="local-$(date +%s%N)-$$"
cp "$jobscript" "$logdir/$id.sh"   # what was submitted, for inspection
setsid bash "$logdir/$id.sh" > "$logdir/$id.out" 2>&1 < /dev/null &
pid=$!
printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$id" "$pid" "$name" "$mem" "$runtime" "$cpus" "$jobscript" \
  >> "${CLUSTER_SUBMIT_LOG:-cluster_submissions.tsv}"
echo "$id"
