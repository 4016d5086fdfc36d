#!/usr/bin/env bash
# The gateway demo, run by `make demo` on vcan0..vcan2 (inside tests/vcan/run).
# Until cogwd exists this shows the three CAN lines and a CANopen-style frame
# exchange on them with can-utils, so a newcomer sees the plumbing is real.
set -euo pipefail
say() { printf '\n== %s\n' "$*"; }

say "The CAN lines the gateway will drive (SocketCAN virtual CAN):"
ip -br link show type vcan

say "Listening on all three lines with candump; each frame should appear on its own line only."
candump -t z -L vcan0 vcan1 vcan2 > /tmp/cogw-demo-dump.log 2>&1 &
dump=$!
sleep 0.5

say "vcan0: node 5 boots (NMT boot-up 0x705), the master starts it (NMT 0x000 01 05)"
cansend vcan0 705#00
cansend vcan0 000#0105
say "vcan1: an SDO upload of 1018h:1 (vendor id) from node 1: request 0x601, response 0x581"
cansend vcan1 601#4018100100000000
cansend vcan1 581#431810010A000000
say "vcan2: a 29-bit frame and a remote frame (node guarding request 0x701)"
cansend vcan2 18FF0001#0102030405060708
cansend vcan2 701#R
sleep 0.5
kill "$dump" 2>/dev/null || true
wait "$dump" 2>/dev/null || true

say "What candump saw (timestamp, line, id#data):"
cat /tmp/cogw-demo-dump.log
lines_seen=$(awk '{print $2}' /tmp/cogw-demo-dump.log | sort | uniq -c | awk '{printf " %s: %s", $2, $1}')
say "Frames per line:${lines_seen}"
rm -f /tmp/cogw-demo-dump.log
say "Demo done. The daemon cogwd and its clients replace this script as they land."
