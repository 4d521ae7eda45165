#!/usr/bin/env bash
# Starts (or stops) a single-node Slurm cluster on this machine: munged, slurmctld and
# slurmd, as root, configured from scripts/slurm/slurm.conf.in. Debian/Ubuntu:
#   apt-get install -y slurm-wlm munge
#   scripts/slurm/single-node.sh start     # then sinfo shows the node idle
#   scripts/slurm/single-node.sh stop
# State and logs go to $SLURM_STATE (default /tmp/slurm-local).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
state=${SLURM_STATE:-/tmp/slurm-local}
host=$(hostname -s)
case "${1:-start}" in
start)
    mkdir -p "$state/slurmctld" "$state/slurmd" /etc/slurm /run/munge
    cpus=$(nproc)
    # Leave the OS some memory; Slurm refuses a node with less than it was told.
    mem=$(( $(awk '/MemTotal/ {print int($2 / 1024)}' /proc/meminfo) * 3 / 4 ))
    sed -e "s/@HOST@/$host/g" -e "s/@CPUS@/$cpus/" -e "s/@MEM@/$mem/" \
        -e "s#@STATE@#$state#g" "$here/slurm.conf.in" >/etc/slurm/slurm.conf
    [ -s /etc/munge/munge.key ] || mungekey --create
    chown -R munge:munge /etc/munge /run/munge /var/lib/munge /var/log/munge 2>/dev/null || true
    pgrep -x munged >/dev/null || runuser -u munge -- /usr/sbin/munged
    munge -n | unmunge >/dev/null          # authentication works
    /usr/sbin/slurmctld                    # daemonizes; pid in $state/slurmctld.pid
    /usr/sbin/slurmd
    for _ in $(seq 30); do
        sinfo -h -o %T 2>/dev/null | grep -q idle && break
        sleep 1
    done
    sinfo
    ;;
stop)
    for d in slurmd slurmctld; do
        [ -f "$state/$d.pid" ] && kill "$(cat "$state/$d.pid")" 2>/dev/null || true
    done
    ;;
*)
    echo "usage: $0 start|stop" >&2
    exit 2
    ;;
esac
