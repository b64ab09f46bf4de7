#!/usr/bin/env bash
# Bring up a one-node SLURM cluster on this machine (localhost, every CPU), for `make test-cluster`.
#
# Installs Debian's slurm-wlm and munge when they are missing (needs root and the package
# registry), writes /etc/slurm/slurm.conf for this host, starts munged, slurmctld and slurmd, and
# waits until the node takes jobs. Idempotent: a cluster that already answers is left alone.
# No accounting database: Snakemake's SLURM executor queries job states with squeue, so jobs stay
# visible for MinJobAge seconds after they end (see profiles/slurm-local/config.yaml).
set -euo pipefail

MIN_JOB_AGE_S=600     # how long squeue still shows a finished job (the executor polls it)
READY_TIMEOUT_S=60    # how long to wait for the node to become idle
STATE_DIR=/var/spool/slurm-local

cluster_answers() { sinfo -h -o '%t' 2>/dev/null | grep -qE '^(idle|mix|alloc)'; }

if command -v sinfo >/dev/null && cluster_answers; then
    echo "slurm-local: a cluster already answers (sinfo)"; exit 0
fi
if [ "$(id -u)" != 0 ]; then
    echo "slurm-local: needs root to install and start slurm-wlm and munge" >&2; exit 1
fi
if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
    echo "slurm-local: installing slurm-wlm and munge (apt-get)"
    DEBIAN_FRONTEND=noninteractive apt-get install -y -q slurm-wlm munge >/dev/null
fi

host=$(hostname -s)
cpus=$(nproc)
mem_mb=$(( $(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 - 1024 ))
mkdir -p /etc/slurm "$STATE_DIR/ctld" "$STATE_DIR/d" /var/log/slurm-local /run/munge
cat > /etc/slurm/slurm.conf <<CONF
# written by profiles/slurm-local/up.sh: a one-node cluster for testing the workflow's SLURM profile
ClusterName=feeder-local
SlurmctldHost=$host
SlurmUser=root
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU_Memory
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MinJobAge=$MIN_JOB_AGE_S
ReturnToService=2
StateSaveLocation=$STATE_DIR/ctld
SlurmdSpoolDir=$STATE_DIR/d
SlurmctldPidFile=/run/slurmctld-local.pid
SlurmdPidFile=/run/slurmd-local.pid
SlurmctldLogFile=/var/log/slurm-local/slurmctld.log
SlurmdLogFile=/var/log/slurm-local/slurmd.log
NodeName=$host CPUs=$cpus RealMemory=$mem_mb State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF

if [ ! -s /etc/munge/munge.key ]; then
    mungekey --create --keyfile=/etc/munge/munge.key 2>/dev/null || \
        dd if=/dev/urandom bs=1 count=1024 of=/etc/munge/munge.key status=none
fi
chown munge:munge /etc/munge/munge.key /run/munge 2>/dev/null || true
chmod 400 /etc/munge/munge.key
pgrep -x munged >/dev/null || runuser -u munge -- munged || munged --force
pgrep -x slurmctld >/dev/null || slurmctld
pgrep -x slurmd >/dev/null || slurmd

for _ in $(seq "$READY_TIMEOUT_S"); do
    if cluster_answers; then
        scontrol update nodename="$host" state=resume >/dev/null 2>&1 || true
        echo "slurm-local: node $host up with $cpus CPUs, partition debug"; exit 0
    fi
    scontrol update nodename="$host" state=resume >/dev/null 2>&1 || true
    sleep 1
done
echo "slurm-local: the node did not come up in ${READY_TIMEOUT_S}s; see /var/log/slurm-local/" >&2
sinfo >&2 || true
exit 1
