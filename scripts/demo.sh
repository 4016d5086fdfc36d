#!/usr/bin/env bash
# The cogw demo, run by `make demo` on vcan0..vcan2 (inside tests/vcan/run,
# natively or in a throwaway VM). A scripted session a newcomer can follow:
# two simulated devices, the daemon cogwd on its embedded default
# configuration, and the CLI cogwctl talking to it through the mailbox, then
# socat through the CiA 309-3 ASCII gateway cogw-ascii, then an MQTT broker
# (mosquitto) through the MQTT bridge cogw-mqtt.
#
# Every step must work: set -e, and a trap that stops every process this
# script started and removes its files, whatever happens. Exit 0 only when
# the whole session went through.
set -euo pipefail

top=$(cd "$(dirname "$0")/.." && pwd)
cd "$top"
bin=${COGW_DEMO_BIN:-build/rel/bin}
work=/tmp/cogw-demo.$$
pids=()
step=0
t_start=$SECONDS

say() { printf '\n\033[1m== %s\033[0m\n' "$*"; }
explain() { printf '   %s\n' "$@"; }
# Show a command, then run it (its output follows).
show() { printf '\n$ %s\n' "$*"; "$@"; }
# Show and run the CLI (the real path is build/rel/bin/cogwctl).
ctl() { printf '\n$ cogwctl %s\n' "$*"; "$bin/cogwctl" "$@"; }
fail() { printf '\ndemo: FAILED: %s\n' "$*" >&2; exit 1; }
# Poll a command until it succeeds: no fixed sleeps as synchronisation.
wait_for() {
	local what=$1 timeout_s=$2; shift 2
	local deadline=$((SECONDS + timeout_s))
	until "$@" >/dev/null 2>&1; do
		[ "$SECONDS" -lt "$deadline" ] || fail "timed out after ${timeout_s}s waiting for $what"
		sleep 0.2
	done
}

cleanup() {
	local rc=$?
	set +e
	for ((i = ${#pids[@]} - 1; i >= 0; i--)); do
		kill -TERM "${pids[i]}" 2>/dev/null
	done
	for p in "${pids[@]}"; do
		for _ in $(seq 50); do kill -0 "$p" 2>/dev/null || break; sleep 0.1; done
		kill -KILL "$p" 2>/dev/null
		wait "$p" 2>/dev/null
	done
	if [ "$rc" -ne 0 ] && [ -d "$work" ]; then
		for f in "$work"/*.log; do
			[ -f "$f" ] || continue
			printf '\n--- last lines of %s\n' "$f" >&2
			tail -n 15 "$f" >&2
		done
	fi
	rm -f /dev/mqueue/cogw.main.* 2>/dev/null
	rm -rf "$work"
	exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

for p in cogwd cosim cogwctl cogw-ascii cogw-mqtt; do
	[ -x "$bin/$p" ] || fail "$bin/$p is missing: run 'make' first"
done
mkdir -p "$work/state"

say "1. Three virtual CAN lines"
explain "cogwd drives one SocketCAN interface per line. Here they are vcan0..vcan2,"
explain "the kernel's virtual CAN: real sockets and frames, no hardware."
show ip -br link show type vcan

say "2. The daemon cogwd, on its embedded default configuration"
explain "No --config: cogwd runs on the configuration compiled into it (etc/cogw.json:"
explain "3 lines vcan0..vcan2, its own node-ID 127 on each, on line 0 an RPDO that"
explain "receives the transducer's TPDO into object B000h) with a CiA 302-2 manager on"
explain "lines 0 and 1: node 1 on line 0 and node 2 on line 1 are mandatory, their"
explain "identity is checked against 1018h, their heartbeats are supervised. Node 1 also"
explain "gets a configuration (CiA 302-3) from the DCF file etc/transducer.dcf, converted"
explain "to a concise DCF when cogwd loads its configuration. --state-dir"
explain "only moves where 1010h \"save\" would write, into /tmp (the rest of this machine"
explain "is read-only in the VM)."
printf '\n$ cogwd --state-dir %s\n' "$work/state"
"$bin/cogwd" --state-dir "$work/state" >"$work/cogwd.log" 2>&1 &
pids+=($!)
cogwd_pid=$!
wait_for "cogwd's mailbox" 10 "$bin/cogwctl" --timeout 1000 status
explain "cogwd is up: one thread and one mailbox command queue per line"
explain "($(ls /dev/mqueue | grep -c '^cogw\.main\.line') queues /cogw.main.line<N>.cmd)."
explain "" "No device answers yet: the managers wait for their mandatory nodes."
ctl manager 0

say "3. Two simulated CANopen devices (cosim) are switched on"
explain "vcan0: the STI pressure transducer (etc/devices/sti-pressure.json), node 1. It sends its pressure"
explain "       (REAL32, PSI) in TPDO 1 (COB-ID 181h) once a second while OPERATIONAL."
explain "vcan1: a CiA 401-style I/O module, node 2."
explain "Their boot-up messages make the managers boot them: device type 1000h,"
explain "identity 1018h, node 1's configuration download, error control, then NMT"
explain "start. The boot events, as any client sees them (cogwctl monitor --class"
explain "boot,manager):"
"$bin/cogwctl" monitor --class boot,manager --duration 6 >"$work/boot.txt" 2>&1 &
mon_pid=$!
sleep 0.5
"$bin/cosim" --interface vcan0 --device etc/devices/sti-pressure.json >"$work/cosim-vcan0.log" 2>&1 &
pids+=($!)
"$bin/cosim" --interface vcan1 --device etc/devices/io-generic.json --loopback >"$work/cosim-vcan1.log" 2>&1 &
pids+=($!)
wait "$mon_pid" || true
cat "$work/boot.txt"
grep -q "node 1 boot start ok: booted" "$work/boot.txt" || fail "node 1 was not booted by the manager"
grep -q "node 2 boot start ok: booted" "$work/boot.txt" || fail "node 2 was not booted by the manager"
grep -q "node 1 boot configure ok: [0-9]* concise DCF entries downloaded" "$work/boot.txt" ||
	fail "node 1's configuration was not downloaded during its boot"
printf '   started: cosim on vcan0 (pid %s), cosim on vcan1 (pid %s)\n' "${pids[1]}" "${pids[2]}"
ctl manager 0
ctl diag 0 1

say "3b. The transducer's configuration came from a DCF file"
explain "The \"configure\" step above wrote what etc/transducer.dcf holds into node 1,"
explain "entry by entry, as cogwctl shows offline (the same conversion cogwd made):"
ctl dcf check etc/transducer.dcf --list --node 1
explain "" "Read back from the device: its heartbeat time 1017h (the device's own default"
explain "is 1000 ms), its TPDO 1 event timer 1800h:5 (default 1000 ms), and 1020h, the"
explain "configuration date/time the manager wrote after the download (a later boot with"
explain "the same 1020h skips the download):"
ctl sdo read 0 1 1017 0 u16 | tee "$work/hb.txt"
ctl sdo read 0 1 1800 5 u16 | tee "$work/et.txt"
ctl sdo read 0 1 1020 1 u32
ctl sdo read 0 1 1020 2 u32
grep -q "= 500\b" "$work/hb.txt" || fail "node 1's heartbeat time is not the DCF's 500 ms"
grep -q "= 500\b" "$work/et.txt" || fail "node 1's TPDO 1 event timer is not the DCF's 500 ms"

say "4. The node table"
explain "Clients never touch CAN: cogwctl asks the daemon through its mailbox."
explain "Each line lists the nodes it has heard; heartbeats tell their NMT state."
wait_for "node 1's heartbeat on line 0" 10 sh -c "'$bin/cogwctl' --json status 0 | grep -q '\"node\":1,\"nmt_state\":\"operational\"'"
wait_for "node 2's heartbeat on line 1" 10 sh -c "'$bin/cogwctl' --json status 1 | grep -q '\"node\":2,'"
ctl status

say "5. An SDO read: the transducer's identity 1018h"
explain "The daemon is the SDO client; cogwctl names line, node, index, sub-index and a"
explain "type to show the value with. Vendor-ID, product code, revision, serial number:"
ctl sdo read 0 1 1018 1 u32
ctl sdo read 0 1 1018 2 u32
ctl sdo read 0 1 1018 3 u32
ctl sdo read 0 1 1018 4 u32
explain "" "Longer values travel segmented, transparently (the device name, 1008h):"
ctl sdo read 0 1 1008 0 string
explain "" "A device refuses what it does not have; the abort code comes with its meaning"
explain "and cogwctl exits with status 1 (a script can tell it from a timeout, 4):"
set +e
ctl sdo read 0 1 2001 0 u32
rc=$?
set -e
[ "$rc" -eq 1 ] || fail "the read of the missing object 2001h should exit 1, it exited $rc"
explain "(exit status $rc, as expected)"

say "6. An SDO write: the transducer's heartbeat time 1017h"
explain "Faster heartbeats from node 1: 250 ms instead of the DCF's 500 ms, then read back."
ctl sdo write 0 1 1017 0 u16 250
ctl sdo read 0 1 1017 0 u16
explain "" "The heartbeats (700h + 1) on line 0 for 2 seconds, as raw frames the daemon receives:"
ctl raw dump 0 701 --duration 2
explain "(about 8 frames: one every 250 ms now)"

say "7. Live pressure: PDO events"
explain "PDOs only run in OPERATIONAL. The manager started node 1 and the daemon's own"
explain "node on line 0, whose RPDO 1 receives the transducer's TPDO 1 into B000h:"
explain "" "A minute of live pressure, shortened to 5 seconds. The pressure ramps from 0 to"
explain "50 PSI over 20 s; --float shows the 4-byte values as REAL32:"
ctl monitor --line 0 --class pdo --float --duration 5 2>&1 | tee "$work/pdo.txt"
n_pdo=$(grep -c "RPDO 1: B000:00 = " "$work/pdo.txt" || true)
[ "$n_pdo" -ge 2 ] || fail "expected pressure PDO events, saw $n_pdo"
explain "" "The latest value also stays in the daemon's process image B000h, readable at"
explain "any time (the ramp starts again from 0 after 50 PSI, so it may have wrapped):"
ctl pdo read 0 b000 0 r32

say "8. The gateway between the lines (CiA 302-7)"
explain "cogwd is also a gateway: every line is a network (ids 1..3), and each line's"
explain "routing table 1F2Ch says where the other networks are. The table of line 0:"
ctl route 0
explain "" "A service tool on vcan0 (here: cansend) reaches node 2, which is on vcan1"
explain "(network 2), through the daemon's SDO server on vcan0 (node 127): first the"
explain "network indication E0 02 00 02 (network 2, node 2), confirmed with the same"
explain "bytes, then an ordinary SDO read of 1018h:1 that the gateway relays to node 2:"
timeout 10 candump -n 2 vcan0,5FF:7FF >"$work/netind.txt" 2>&1 &
dump_pid=$!
sleep 0.3
show cansend vcan0 67F#E002000200000000
sleep 0.3
show cansend vcan0 67F#4018100100000000
wait "$dump_pid" || fail "no answer from the gateway on vcan0 (5FFh)"
explain "" "The answers on vcan0, from the gateway (5FFh): the confirmation, then node 2's"
explain "answer with its vendor-ID, relayed from vcan1:"
cat "$work/netind.txt"
grep -q "E0 02 00 02" "$work/netind.txt" || fail "the network indication was not confirmed"
grep -q "43 18 10 01" "$work/netind.txt" || fail "node 2's answer did not come back"
explain "" "Mailbox clients do the same with --net: asked on line 0, node 2 of network 2:"
ctl sdo read 0 2 1018 1 u32 --net 2
explain "" "EMCY routing: 1F2Fh:1 = 2 on line 0 forwards node 1's emergencies to network 2."
explain "A fake EMCY from node 1 on vcan0 (code 1234h) comes out on vcan1 from the gateway"
explain "(80h + 127 = 0FFh) as F000h with the source network, node and original code:"
timeout 10 candump -n 1 vcan1,0FF:7FF >"$work/emcy.txt" 2>&1 &
dump_pid=$!
sleep 0.3
show cansend vcan0 081#3412010000000000
wait "$dump_pid" || fail "the EMCY was not forwarded to vcan1"
cat "$work/emcy.txt"
grep -q "00 F0 .. 01 00 01 34 12" "$work/emcy.txt" || fail "unexpected forwarded EMCY"
explain "" "PDO forwarding: B000h is one process image for all lines. Line 1's TPDO 1 (1FFh)"
explain "maps it, so the pressure that line 0 receives from the transducer goes out on"
explain "vcan1 as soon as it changes: the manager of line 1 started the daemon's own node"
explain "there (OPERATIONAL) when it started the network:"
timeout 10 candump -n 3 vcan1,1FF:7FF >"$work/fwd.txt" 2>&1 || fail "no forwarded pressure PDO on vcan1"
cat "$work/fwd.txt"
ctl pdo read 1 b000 0 r32
explain "" "The counters of the routes and of the forwarding:"
ctl route 0 1

say "8b. Device objects: the I/O module by its own objects"
explain "Node 2 on line 1 has \"pdo\": \"auto\": while it booted, the manager read its PDO"
explain "layout over SDO, and the daemon set up its own free RPDOs to receive the node's"
explain "TPDOs and its free TPDOs to send the node's RPDOs (docs/devices.md):"
wait_for "node 2's mirror" 20 sh -c "'$bin/cogwctl' --json pdo map 1 2 | grep -q '\"mirror\":\"full\"'"
ctl pdo map 1 2
explain "" "Watching its digital input 6000h:1 (in its TPDO 1), typed, while a client writes"
explain "its digital outputs 6200h:1 and :2 (both in its RPDO 1). cosim runs with --loopback:"
explain "the outputs come back as inputs. The first write is held (the RPDO goes out only"
explain "when every object in it has a value), the second sends the frame:"
"$bin/cogwctl" watch 1 2 6000 1 --count 2 --duration 15 >"$work/watch.txt" 2>"$work/watch.err" &
watch_pid=$!
wait_for "the watch" 10 grep -q "watching 1 object" "$work/watch.err"
printf '\n$ cogwctl watch 1 2 6000 1 --count 2 &\n'
ctl dev write 1 2 6200 1 u8 3
ctl dev write 1 2 6200 2 u8 5
wait "$watch_pid" || fail "cogwctl watch ended with an error"
cat "$work/watch.txt"
grep -q "6000:01 UNSIGNED8 = 3" "$work/watch.txt" || fail "the written output did not come back as a watched input"
explain "" "Reading: from the daemon's mirror when the value is fresh enough (here: up to a"
explain "minute old; the line's default is 1 s), else by SDO (6200h is in no TPDO):"
ctl dev read 1 2 6000 1 --max-age 60000
ctl dev read 1 2 6200 2

say "9. CiA 309-3 ASCII commands over a socket (cogw-ascii)"
explain "cogw-ascii is one more mailbox client: it serves the CiA 309-3 ASCII command"
explain "syntax (canopend's, coctl's) on a UNIX socket (and TCP if configured) to any"
explain "number of connections, each with its own default network and node. Here a"
explain "plain socat is the client: reads on networks 1 and 2, defaults, a missing"
explain "object (an SDO abort as its code), the version (docs/ascii.md):"
printf '\n$ cogw-ascii --socket %s\n' "$work/ascii.sock"
"$bin/cogw-ascii" --socket "$work/ascii.sock" >"$work/cogw-ascii.log" 2>&1 &
pids+=($!)
ascii_pid=$!
wait_for "cogw-ascii's socket" 10 test -S "$work/ascii.sock"
ascii_in='[1] 1 1 r 0x1018 1 u32
[2] 1 1 r 0x1008 0 vs
[3] 2 2 r 0x1000 0 x32
[4] set network 1
[5] set node 1
[6] r 0x1017 0 u16
[7] r 0x6666 0 u8
[8] info version'
printf '\n$ socat - UNIX-CONNECT:%s <<EOF\n%s\nEOF\n' "$work/ascii.sock" "$ascii_in"
printf '%s\n' "$ascii_in" | timeout 20 socat -t 10 - UNIX-CONNECT:"$work/ascii.sock" | tr -d '\r' | tee "$work/ascii.out"
grep -qx '\[1\] 592' "$work/ascii.out" || fail "cogw-ascii: unexpected answer to [1]"
grep -qx '\[2\] "STI-SIM"' "$work/ascii.out" || fail "cogw-ascii: unexpected answer to [2]"
grep -qx '\[7\] ERROR: 0x06020000' "$work/ascii.out" || fail "cogw-ascii: unexpected answer to [7]"
kill -TERM "$ascii_pid"
wait "$ascii_pid" || fail "cogw-ascii did not exit cleanly"
pids=("${pids[@]:0:3}")

say "9b. The gateway on an MQTT broker (cogw-mqtt)"
explain "cogw-mqtt is one more mailbox client: it publishes every network's state,"
explain "emergencies and counters to an MQTT broker, and takes requests from it"
explain "(docs/mqtt.md). A mosquitto broker on loopback, then the bridge as gateway \"demo\":"
mqtt_port=18883
printf 'listener %s 127.0.0.1\nallow_anonymous true\npersistence false\n' "$mqtt_port" >"$work/mosquitto.conf"
[ "$(id -u)" -ne 0 ] || echo "user root" >>"$work/mosquitto.conf"
mosquitto -c "$work/mosquitto.conf" >"$work/mosquitto.log" 2>&1 &
pids+=($!)
wait_for "the MQTT broker" 10 timeout 5 mosquitto_sub -h 127.0.0.1 -p "$mqtt_port" -t x -W 1 -C 1 -E
cat >"$work/cogw-mqtt.json" <<JSON
{"version": 1, "gateway": "demo", "broker": {"uri": "mqtt://127.0.0.1:$mqtt_port"}}
JSON
printf '\n$ cogw-mqtt --config %s   # %s\n' "$work/cogw-mqtt.json" "$(cat "$work/cogw-mqtt.json")"
"$bin/cogw-mqtt" --config "$work/cogw-mqtt.json" >"$work/cogw-mqtt.log" 2>&1 &
pids+=($!)
mqtt_pid=$!
explain "" "One value: node 1's NMT state, retained on its topic (any subscriber gets it at once):"
wait_for "node 1's state on the broker" 30 sh -c "timeout 5 mosquitto_sub -h 127.0.0.1 -p $mqtt_port -t cogw/demo/net/1/node/1/nmt -C 1 -W 3 | grep -q '\"operational\"'"
show mosquitto_sub -h 127.0.0.1 -p "$mqtt_port" -t 'cogw/demo/status' -t 'cogw/demo/net/1/node/1/nmt' -v -C 2 -W 5
explain "" "One request: an MQTT 5 request/response (mosquitto_rr sets the response topic and"
explain "correlation data), reading the transducer's pressure 2003h over SDO:"
show mosquitto_rr -h 127.0.0.1 -p "$mqtt_port" -t cogw/demo/request -e demo/replies -W 10 \
	-m '{"op":"sdo_read","net":1,"node":1,"index":"0x2003","sub":0,"type":"r32"}' | tee "$work/mqtt-reply.txt"
grep -q '"ok":true' "$work/mqtt-reply.txt" || fail "cogw-mqtt: the request was not answered"
explain "" "The bridge's role is read (the default): a write is refused with a reason:"
show mosquitto_rr -h 127.0.0.1 -p "$mqtt_port" -t cogw/demo/request -e demo/replies -W 10 \
	-m '{"op":"nmt","net":1,"node":1,"command":"stop"}' | tee "$work/mqtt-refusal.txt"
grep -q '"error":"refused_role"' "$work/mqtt-refusal.txt" || fail "cogw-mqtt: the write was not refused"
kill -TERM "$mqtt_pid"
wait "$mqtt_pid" || fail "cogw-mqtt did not exit cleanly"
kill -TERM "${pids[3]}"
wait "${pids[3]}" 2>/dev/null || true
pids=("${pids[@]:0:3}")

say "10. A clean stop"
explain "SIGTERM: cogwd stops its line threads, removes its mailbox queues, exits 0."
kill -TERM "$cogwd_pid"
set +e
wait "$cogwd_pid"
rc=$?
set -e
pids=("${pids[@]:1:2}")
[ "$rc" -eq 0 ] || fail "cogwd exited with status $rc"
left=$(ls /dev/mqueue | grep -c '^cogw\.main\.' || true)
[ "$left" -eq 0 ] || fail "$left mailbox queues left behind"
printf '   cogwd exited with status 0, no mailbox queue left.\n'
for p in "${pids[@]}"; do kill -TERM "$p"; wait "$p" || fail "cosim (pid $p) did not exit cleanly"; done
pids=()
printf '   the simulated devices stopped.\n'

say "Summary ($((SECONDS - t_start)) s)"
explain "- cogwd drove 3 CAN lines; its CiA 302-2 managers booted the two simulated"
explain "  devices by themselves when they were switched on (device type, identity,"
explain "  heartbeat, NMT start: step 3) and supervise their heartbeats (step 4)."
explain "- During its boot the transducer got its heartbeat time and TPDO 1 settings from"
explain "  etc/transducer.dcf (CiA 302-3 configuration download, step 3b)."
explain "- cogwctl read the transducer's identity 1018h and name 1008h over SDO, showed an"
explain "  SDO abort with its meaning, and set its heartbeat time 1017h to 250 ms."
explain "- Started by the manager, the transducer sent $n_pdo pressure PDOs as live events (step 7)."
explain "- As a gateway (step 8) cogwd relayed an SDO request entering on vcan0 to node 2 on"
explain "  vcan1, forwarded an EMCY from vcan0 to vcan1, and the pressure by PDO to vcan1."
explain "- Node 2's objects by their own names (step 8b): its PDO layout learnt over SDO,"
explain "  mirrored on the daemon's PDOs; a watched input typed as it changed, outputs"
explain "  written by the device's RPDO."
explain "- socat, a plain tool, read the devices through cogw-ascii in the CiA 309-3 ASCII"
explain "  syntax (step 9)."
explain "- mosquitto_sub saw the retained state of node 1 on an MQTT broker, and an MQTT 5"
explain "  request read its pressure through cogw-mqtt (step 9b)."
explain "- Everything went through the mailbox (POSIX message queues); nothing was left over."
explain "Next: 'cogwctl --help', docs/cogwctl.md, docs/config.md, docs/gateway.md, docs/mailbox.md,"
explain "      docs/ascii.md, docs/mqtt.md."
printf '\ndemo: OK\n'
