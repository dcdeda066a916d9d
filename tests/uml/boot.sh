#!/bin/sh
# init of a user-mode Linux guest for tests/test_vcan_uml.py: real SocketCAN (vcan) in a throwaway kernel.
#
# Booted as:  linux.uml mem=256M root=/dev/root rootfstype=hostfs rootflags=/ rw init=THIS_FILE \
#                       con0=null,fd:1 con=null quiet attica_job=/path/job.sh </dev/null
# The host's file system is the guest's root (hostfs), so the job sees the checkout, the Python
# interpreter and can-utils at their host paths. Kernel command line words of the form key=value
# that the kernel does not know are handed to init as environment variables: attica_job names the
# shell script to run. Its output goes to $attica_job.log, its exit status to $attica_job.status
# (written last: the host treats a missing status file as "the guest died").
PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin
export PATH
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t tmpfs tmpfs /dev/shm 2>/dev/null
job="${attica_job:?attica_job=/path/to/job.sh missing from the kernel command line}"
log="$job.log"
status=0
{
    ver=$(uname -r)
    mods=/usr/lib/uml/modules/$ver/kernel
    for m in net/can/can.ko net/can/can-raw.ko drivers/net/can/dev/can-dev.ko drivers/net/can/vcan.ko; do
        insmod "$mods/$m" || { echo "uml: insmod $mods/$m failed"; status=90; }
    done
    if [ "$status" = 0 ]; then
        ip link add dev vcan0 type vcan && ip link set vcan0 mtu 72 && ip link set up vcan0 || status=91
    fi
    ip link set lo up
    if [ "$status" = 0 ]; then
        echo "uml: kernel $ver, vcan0 up (mtu 72)"
        /bin/sh "$job"
        status=$?
    fi
} >"$log" 2>&1
echo "$status" >"$job.status"
sync
poweroff -f
