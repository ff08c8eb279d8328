#!/usr/bin/env bash
# Create a virtual SocketCAN interface for HIL on a Linux host (needs root and the vcan kernel module):
#   sudo scripts/setup-vcan.sh [NAME]      (default vcan0)
# Then use [can] interface = "socketcan", channel = "vcan0". Remove with: sudo ip link delete vcan0
set -euo pipefail
name="${1:-vcan0}"
if ! modprobe vcan 2>/dev/null && ! grep -qw vcan /proc/modules; then
  echo "setup-vcan: the vcan kernel module is not available on this kernel" >&2
  exit 1
fi
if ip link show "$name" >/dev/null 2>&1; then
  echo "setup-vcan: $name already exists"
else
  ip link add dev "$name" type vcan
fi
ip link set up "$name"
ip -details link show "$name"
