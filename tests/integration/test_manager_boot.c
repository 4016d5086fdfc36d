/* SPDX-License-Identifier: MIT */
/*
 * The CiA 302-2 manager in the real daemon on vcan with cosim devices
 * (grouped into one VM boot):
 *   (c)+(g) two lines booting at once: line 0 has the transducer (node 1,
 *       mandatory, identity checked) and an I/O module (node 2, optional,
 *       expected with a wrong vendor -> status D, not started); line 1 has
 *       an I/O module as mandatory node 2. Both lines reach OPERATIONAL by
 *       themselves; the devices start late (after the daemon) and are
 *       booted when their boot-up comes. Boot events reach a client.
 *   (f) Request NMT over the mailbox stops a node.
 *   (h) a device on the manager's own node-ID makes that line fatal, not
 *       the other one.
 *   (a)+(b)+(e)+(f) on one line: 10 devices, nodes 1 and 11 mandatory;
 *       node 11 is missing: the line waits, 1F89h runs out, status B, the
 *       network is not started; node 11 is switched on later: it is booted
 *       and the network starts with all 11. A 1F82h write over SDO from
 *       another node (raw frames to the daemon's SDO server) stops node 3.
 *       Node 11's heartbeat stops: 1F80h "stop_all" stops every node.
 *   (d) a keep-alive node found OPERATIONAL is not reset (no reset frame,
 *       no boot-up), the other node of its line is. A second device with
 *       node 2's ID (no boot-up, no heartbeat) answers an SDO read too:
 *       two answers to one request, reported as a duplicate node-ID.
 *   (e) 1F80h "reset_all": a mandatory node's heartbeat stops -> NMT reset
 *       node to all nodes, the network boots again.
 * Run: tests/vcan/run -n 2 -- build/san/tests/integration/test_manager_boot
 */
#include <linux/can.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/manager.h"
#include "core/nmt.h"
#include "mailbox/cogw.h"
#include "tests/integration/support/daemon.h"
#include "tests/integration/support/proc.h"
#include "unity.h"

#define CONFIG                                                                                  \
	"{\"version\": 1, \"mailbox\": {\"instance\": \"mgrt\"}, \"lines\": ["                  \
	"{\"interface\": \"vcan0\", \"bitrate\": 1000000, \"node_id\": 127, "                   \
	" \"manager\": {\"boot_time_ms\": 20000, \"retry_ms\": 500}, \"nodes\": ["              \
	"  {\"id\": 1, \"mandatory\": true, \"heartbeat_ms\": 1500, \"vendor_id\": \"0x250\", " \
	"   \"device_type\": \"0x00040194\", \"serial\": 123456},"                              \
	"  {\"id\": 2, \"heartbeat_ms\": 800, \"vendor_id\": \"0x9999\"}]},"                    \
	"{\"interface\": \"vcan1\", \"bitrate\": 1000000, \"node_id\": 127, "                   \
	" \"manager\": {\"retry_ms\": 500}, \"nodes\": ["                                       \
	"  {\"id\": 2, \"mandatory\": true, \"heartbeat_ms\": 800, \"vendor_id\": \"0x1234\", " \
	"   \"product_code\": \"0x401\"}]}]}"

static daemon_run dmn;
static cosim_run sim0, sim1, intruder, simA, simB, simC, simD;
static cogw *h;

void setUp(void)
{
	memset(&dmn, 0, sizeof dmn);
	memset(&sim0, 0, sizeof sim0);
	memset(&sim1, 0, sizeof sim1);
	memset(&intruder, 0, sizeof intruder);
	memset(&simA, 0, sizeof simA);
	memset(&simB, 0, sizeof simB);
	memset(&simC, 0, sizeof simC);
	memset(&simD, 0, sizeof simD);
	h = NULL;
}

void tearDown(void)
{
	if (h)
		cogw_close(h);
	cosim_stop(&intruder, 3000);
	cosim_stop(&sim0, 3000);
	cosim_stop(&sim1, 3000);
	cosim_stop(&simA, 3000);
	cosim_stop(&simB, 3000);
	cosim_stop(&simC, 3000);
	cosim_stop(&simD, 3000);
	daemon_cleanup(&dmn);
	daemon_unlink_queues("mgrt");
}

static int wait_state(unsigned line, uint8_t state, int timeout_ms, mbx_mgr_status *st)
{
	uint64_t until = mono_ms() + (uint64_t)timeout_ms;
	for (;;) {
		int rc = cogw_mgr_status(h, line, st, 3000);
		if (rc == 0 && st->state == state)
			return 0;
		if (mono_ms() > until)
			return rc ? rc : -1;
		sleep_ms(100);
	}
}

static bool bit(const mbx_mgr_bits *b, unsigned n)
{
	return (b->w[n / 32] >> (n % 32)) & 1u;
}

static void test_two_lines_boot_identity_request_own_id(void)
{
	mbx_mgr_status st;
	mbx_mgr_node_diag d;
	cogw_msg m;
	bool booted1 = false, failed_d = false;

	TEST_ASSERT_EQUAL_INT(0, daemon_start(&dmn, &(daemon_opts){ .config_json = CONFIG,
								    .instance = "mgrt",
								    .n_lines = 2 }));
	TEST_ASSERT_EQUAL_INT(0, cogw_open(&h, "mgrt"));
	TEST_ASSERT_EQUAL_INT(0,
			      cogw_subscribe(h, 0, MBX_EVC_BOOT | MBX_EVC_MANAGER, NULL, 0, 3000));
	/* the devices are switched on after the daemon: late nodes */
	const char *dev0[] = { "etc/devices/sti-pressure.json:1", "etc/devices/io-generic.json:2",
			       NULL };
	const char *dev1[] = { "etc/devices/io-generic.json:2", NULL };
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim0, dmn.dir, 0, dev0, NULL));
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim1, dmn.dir, 1, dev1, NULL));

	TEST_ASSERT_EQUAL_INT(0, wait_state(0, CO_MGR_OPERATIONAL, 30000, &st));
	TEST_ASSERT_TRUE(bit(&st.booted, 1));
	TEST_ASSERT_FALSE(bit(&st.booted, 2));
	TEST_ASSERT_TRUE(bit(&st.mismatch, 2));
	/* the operational list follows the heartbeats: node 1's next one */
	for (uint64_t t = mono_ms() + 5000; !bit(&st.operational, 1) && mono_ms() < t;) {
		sleep_ms(100);
		TEST_ASSERT_EQUAL_INT(0, cogw_mgr_status(h, 0, &st, 3000));
	}
	TEST_ASSERT_TRUE(bit(&st.operational, 1));
	TEST_ASSERT_FALSE(bit(&st.operational, 2));
	TEST_ASSERT_TRUE(st.flags & CO_MGR_F_OPTIONAL_MISSING);
	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_node_diag(h, 0, 2, &d, 3000));
	TEST_ASSERT_EQUAL('D', d.status);
	TEST_ASSERT_EQUAL_HEX16(0x1018, d.index);
	TEST_ASSERT_EQUAL_UINT8(1, d.sub);
	TEST_ASSERT_EQUAL_HEX32(0x1234, d.value);
	TEST_ASSERT_EQUAL_INT(0, wait_state(1, CO_MGR_OPERATIONAL, 30000, &st));
	TEST_ASSERT_TRUE(bit(&st.booted, 2));

	/* the boot events reached the client */
	uint64_t until = mono_ms() + 5000;
	while ((!booted1 || !failed_d) && mono_ms() < until) {
		if (cogw_recv(h, &m, 200) != 0)
			continue;
		if (m.code == MBX_EV_MGR_BOOT && m.line == 0) {
			mbx_ev_mgr e;
			memcpy(&e, m.data, sizeof e);
			booted1 = booted1 || (e.node == 1 && e.done && !e.status);
			failed_d = failed_d || (e.node == 2 && e.status == 'D');
		}
		cogw_msg_release(&m);
	}
	TEST_ASSERT_TRUE_MESSAGE(booted1, "no 'booted' event for node 1");
	TEST_ASSERT_TRUE_MESSAGE(failed_d, "no status D event for node 2");

	/* (f) Request NMT: stop node 1 on line 0 */
	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_request_nmt(h, 0, 1, 4, 3000));
	until = mono_ms() + 5000;
	do {
		sleep_ms(200);
		TEST_ASSERT_EQUAL_INT(0, cogw_mgr_status(h, 0, &st, 3000));
	} while (!bit(&st.stopped, 1) && mono_ms() < until);
	TEST_ASSERT_TRUE(bit(&st.stopped, 1));

	/* (g) one frame on the manager's own EMCY and SDO answer identities
	 * (0FFh, 5FFh) on line 1: anyone can send it, it proves no second
	 * device. Reported and counted; the line stays operational. */
	int fd = can_open_raw("vcan1");
	TEST_ASSERT_TRUE(fd >= 0);
	TEST_ASSERT_EQUAL_INT(0, cogw_subscribe(h, 1, MBX_EVC_MANAGER, NULL, 0, 3000));
	TEST_ASSERT_EQUAL_INT(0, can_send_std(fd, 0x080 + 127,
					      (const uint8_t[]){ 0x00, 0x81, 0x11, 0, 0, 0, 0, 0 },
					      8));
	TEST_ASSERT_EQUAL_INT(0, can_send_std(fd, 0x580 + 127,
					      (const uint8_t[]){ 0x43, 0x00, 0x10, 0, 0, 0, 0, 0 },
					      8));
	close(fd);
	bool own_emcy = false, own_sdo = false;
	until = mono_ms() + 5000;
	while ((!own_emcy || !own_sdo) && mono_ms() < until) {
		if (cogw_recv(h, &m, 200) != 0)
			continue;
		if (m.code == MBX_EV_MGR_NODE && m.line == 1) {
			mbx_ev_mgr e;
			memcpy(&e, m.data, sizeof e);
			own_emcy = own_emcy || (e.what == CO_MGR_NODE_OWN_ID && e.value == 0x0FF);
			own_sdo = own_sdo || (e.what == CO_MGR_NODE_OWN_ID && e.value == 0x5FF);
		}
		cogw_msg_release(&m);
	}
	TEST_ASSERT_TRUE_MESSAGE(own_emcy, "no own-id event for 0FFh");
	TEST_ASSERT_TRUE_MESSAGE(own_sdo, "no own-id event for 5FFh");
	sleep_ms(300);
	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_status(h, 1, &st, 3000));
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, st.state);
	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_node_diag(h, 1, 127, &d, 3000));
	TEST_ASSERT_EQUAL_UINT32(2, d.own_id_frames);

	/* (h) a device claims the manager's node-ID on line 1: a simulated
	 * I/O module configured with node-ID 127 is plugged in (its first
	 * frames, heartbeats on 77Fh, cannot be told from the daemon's own
	 * by cosim_start: it starts off the bus) */
	char dir_h[DAEMON_PATH_MAX + 4];
	snprintf(dir_h, sizeof dir_h, "%s/h", dmn.dir);
	TEST_ASSERT_EQUAL_INT(0, mkdir(dir_h, 0700));
	const char *dev_h[] = { "etc/devices/io-generic.json:127", NULL };
	const char *off_bus[] = { "--silent", NULL };
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&intruder, dir_h, 1, dev_h, off_bus));
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&intruder, "silent off", NULL, 0, 3000));
	TEST_ASSERT_EQUAL_INT(0, wait_state(1, CO_MGR_FATAL, 5000, &st));
	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_node_diag(h, 1, 2, &d, 3000));
	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_status(h, 0, &st, 3000));
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, st.state);
}

#define NODE(id, extra) \
	"{\"id\": " #id ", \"heartbeat_ms\": 1500, \"vendor_id\": \"0x1234\"" extra "}"
#define CONFIG10                                                                                                            \
	"{\"version\": 1, \"mailbox\": {\"instance\": \"mgrt\"}, \"lines\": ["                                              \
	"{\"interface\": \"vcan0\", \"bitrate\": 1000000, \"node_id\": 127, \"sdo_clients\": 4, "                           \
	" \"manager\": {\"boot_time_ms\": 3000, \"retry_ms\": 500, "                                                        \
	"   \"on_mandatory_error\": \"stop_all\"}, \"nodes\": [" NODE(1, ", \"mandatory\": true") "," NODE(2, "") "," NODE( \
		3,                                                                                                          \
		"") "," NODE(4,                                                                                             \
			     "") "," NODE(5,                                                                                \
					  "") "," NODE(6,                                                                   \
						       "") "," NODE(7,                                                      \
								    "") "," NODE(8,                                         \
										 "") "," NODE(9,                            \
											      "") "," NODE(10,              \
													   "") "," NODE(11, \
															", \"mandatory\": true") "]}]}"

static unsigned count_bits(const mbx_mgr_bits *b)
{
	unsigned n = 0;
	for (unsigned i = 1; i < 128; i++)
		n += bit(b, i);
	return n;
}

static void test_ten_devices_missing_mandatory_request_over_sdo_stop_all(void)
{
	mbx_mgr_status st;
	mbx_mgr_node_diag d;

	TEST_ASSERT_EQUAL_INT(0, daemon_start(&dmn, &(daemon_opts){ .config_json = CONFIG10,
								    .instance = "mgrt",
								    .n_lines = 1 }));
	TEST_ASSERT_EQUAL_INT(0, cogw_open(&h, "mgrt"));
	const char *a[] = { "etc/devices/io-generic.json:1", NULL };
	const char *b[] = { "etc/devices/io-generic.json:2", "etc/devices/io-generic.json:3",
			    "etc/devices/io-generic.json:4", "etc/devices/io-generic.json:5",
			    "etc/devices/io-generic.json:6", NULL };
	const char *c[] = { "etc/devices/io-generic.json:7", "etc/devices/io-generic.json:8",
			    "etc/devices/io-generic.json:9", "etc/devices/io-generic.json:10",
			    NULL };
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&simA, dmn.dir, 0, a, NULL));
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&simB, dmn.dir, 0, b, NULL));
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&simC, dmn.dir, 0, c, NULL));

	/* (b) node 11 is missing: after 1F89h the line is booted, not started */
	TEST_ASSERT_EQUAL_INT(0, wait_state(0, CO_MGR_BOOTED, 20000, &st));
	TEST_ASSERT_TRUE(st.flags & CO_MGR_F_MANDATORY_MISSING);
	/* devices switched on after the boot time are booted too, not started */
	for (uint64_t t = mono_ms() + 15000; count_bits(&st.booted) < 10 && mono_ms() < t;) {
		sleep_ms(100);
		TEST_ASSERT_EQUAL_INT(0, cogw_mgr_status(h, 0, &st, 3000));
	}
	TEST_ASSERT_EQUAL(CO_MGR_BOOTED, st.state);
	TEST_ASSERT_EQUAL_UINT(10, count_bits(&st.booted));
	TEST_ASSERT_FALSE(bit(&st.booted, 11));
	TEST_ASSERT_EQUAL_UINT(0, count_bits(&st.operational));
	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_node_diag(h, 0, 11, &d, 3000));
	TEST_ASSERT_EQUAL('B', d.status);
	TEST_ASSERT_EQUAL_HEX16(0x1000, d.index);
	TEST_ASSERT_EQUAL_HEX32(0x05040000, d.abort);
	TEST_ASSERT_EQUAL_UINT8(CO_MGR_NODE_MISSING, d.nmt_state);

	/* it shows up: booted, and the network starts with everybody (a) */
	const char *dd[] = { "etc/devices/io-generic.json:11", NULL };
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&simD, dmn.dir, 0, dd, NULL));
	TEST_ASSERT_EQUAL_INT(0, wait_state(0, CO_MGR_OPERATIONAL, 20000, &st));
	for (uint64_t t = mono_ms() + 5000; count_bits(&st.operational) < 11 && mono_ms() < t;) {
		sleep_ms(100);
		TEST_ASSERT_EQUAL_INT(0, cogw_mgr_status(h, 0, &st, 3000));
	}
	TEST_ASSERT_EQUAL_UINT(11, count_bits(&st.booted));
	TEST_ASSERT_EQUAL_UINT(11, count_bits(&st.operational));

	/* (f) another node writes 1F82h:3 = 4 (stop) over SDO */
	int fd = can_open_raw("vcan0");
	TEST_ASSERT_TRUE(fd >= 0);
	uint8_t req[8] = { 0x2F, 0x82, 0x1F, 0x03, 0x04, 0, 0, 0 }, ans[8];
	TEST_ASSERT_EQUAL_INT(0, can_send_std(fd, 0x67F, req, 8));
	TEST_ASSERT_EQUAL_INT(8, can_wait_id(fd, 0x5FF, ans, 3000));
	TEST_ASSERT_EQUAL_HEX8(0x60, ans[0]);
	close(fd);
	for (uint64_t t = mono_ms() + 5000; !bit(&st.stopped, 3) && mono_ms() < t;) {
		sleep_ms(100);
		TEST_ASSERT_EQUAL_INT(0, cogw_mgr_status(h, 0, &st, 3000));
	}
	TEST_ASSERT_TRUE(bit(&st.stopped, 3));
	TEST_ASSERT_TRUE(bit(&st.operational, 4));

	/* (e) the mandatory node 11 falls silent: stop all (the control socket
	 * of a line belongs to its last cosim: simD) */
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&simD, "hb stop", NULL, 0, 3000));
	TEST_ASSERT_EQUAL_INT(0, wait_state(0, CO_MGR_STOPPED, 10000, &st));
	for (uint64_t t = mono_ms() + 5000; !bit(&st.stopped, 10) && mono_ms() < t;) {
		sleep_ms(100);
		TEST_ASSERT_EQUAL_INT(0, cogw_mgr_status(h, 0, &st, 3000));
	}
	TEST_ASSERT_TRUE(bit(&st.stopped, 10));
	TEST_ASSERT_TRUE(bit(&st.errctrl_lost, 11));
	TEST_ASSERT_FALSE(bit(&st.errctrl_lost, 1));
	TEST_ASSERT_EQUAL_UINT32(1, st.errctrl_events);
}

/* What a line's bus showed: the NMT commands and boot-ups that matter. */
typedef struct bus_watch {
	int fd;
	bool reset_of[128];   /* NMT reset node/comm addressed to n (0 = all) */
	uint8_t reset_cs_all; /* cs of the last reset to all (0 = none) */
	bool bootup_of[128];
} bus_watch;

static void watch_open(bus_watch *w, const char *ifname)
{
	memset(w, 0, sizeof *w);
	w->fd = can_open_raw(ifname);
	TEST_ASSERT_TRUE(w->fd >= 0);
}

static void watch_reset(bus_watch *w)
{
	int fd = w->fd;
	memset(w, 0, sizeof *w);
	w->fd = fd;
}

/* Read what came since the last call (the socket keeps the frames). */
static void watch_drain(bus_watch *w)
{
	uint8_t d[8];
	for (;;) {
		struct can_frame f;
		ssize_t n = recv(w->fd, &f, sizeof f, MSG_DONTWAIT);
		if (n != (ssize_t)sizeof f)
			return;
		memcpy(d, f.data, 8);
		if (f.can_id == 0 && f.len == 2 && (d[0] == 0x81 || d[0] == 0x82) && d[1] < 128) {
			w->reset_of[d[1]] = true;
			if (d[1] == 0)
				w->reset_cs_all = d[0];
		}
		if (f.can_id > 0x700 && f.can_id < 0x780 && f.len == 1 && d[0] == 0)
			w->bootup_of[f.can_id - 0x700] = true;
	}
}

/* Poll the manager status of `line` until `done` holds, draining the
 * watches meanwhile. */
static bool wait_for(unsigned line, bus_watch *w0, bus_watch *w1, int timeout_ms,
		     bool (*done)(const mbx_mgr_status *), mbx_mgr_status *st)
{
	uint64_t until = mono_ms() + (uint64_t)timeout_ms;
	for (;;) {
		watch_drain(w0);
		watch_drain(w1);
		if (cogw_mgr_status(h, line, st, 3000) == 0 && done(st))
			return true;
		if (mono_ms() > until)
			return false;
		sleep_ms(100);
	}
}

static bool both_operational(const mbx_mgr_status *st)
{
	return st->state == CO_MGR_OPERATIONAL && bit(&st->booted, 1) && bit(&st->booted, 2) &&
	       bit(&st->operational, 1) && bit(&st->operational, 2);
}

static bool rebooted_after_loss(const mbx_mgr_status *st)
{
	return st->network_boots >= 2 && both_operational(st);
}

#define CONFIG_KEEP_RESET                                                                        \
	"{\"version\": 1, \"mailbox\": {\"instance\": \"mgrt\"}, \"lines\": ["                   \
	"{\"interface\": \"vcan0\", \"bitrate\": 1000000, \"node_id\": 127, "                    \
	" \"manager\": {\"boot_time_ms\": 20000, \"retry_ms\": 500}, \"nodes\": ["               \
	"  {\"id\": 1, \"mandatory\": true, \"keep_alive\": true, \"heartbeat_ms\": 1500, "      \
	"   \"vendor_id\": \"0x1234\"},"                                                         \
	"  {\"id\": 2, \"heartbeat_ms\": 1500, \"vendor_id\": \"0x1234\"}]},"                    \
	"{\"interface\": \"vcan1\", \"bitrate\": 1000000, \"node_id\": 127, "                    \
	" \"manager\": {\"boot_time_ms\": 20000, \"retry_ms\": 500, "                            \
	"   \"on_mandatory_error\": \"reset_all\"}, \"nodes\": ["                                \
	"  {\"id\": 1, \"mandatory\": true, \"heartbeat_ms\": 1500, \"vendor_id\": \"0x1234\"}," \
	"  {\"id\": 2, \"heartbeat_ms\": 1500, \"vendor_id\": \"0x1234\"}]}]}"

/*
 * (d) line 0: node 1 has the keep-alive bit and is OPERATIONAL already
 * (it started itself) when the daemon comes up: the network boot resets
 * node 2 alone, node 1 gets no reset and sends no boot-up, and is booted
 * (status L, informational) and supervised.
 * (e) line 1, 1F80h bit 4 ("reset_all"): the mandatory node 1's heartbeat
 * stops: NMT reset node to all nodes, both reboot, the network boots again
 * and is started once node 1's heartbeat is back.
 */
static void test_keep_alive_not_reset_and_reset_all_on_mandatory_loss(void)
{
	mbx_mgr_status st;
	bus_watch w0, w1;
	cogw_msg m;

	watch_open(&w0, "vcan0");
	watch_open(&w1, "vcan1");
	const char *alive[] = { "etc/devices/io-generic.json:1", NULL };
	const char *plain[] = { "etc/devices/io-generic.json:2", NULL };
	const char *pair[] = { "etc/devices/io-generic.json:1", "etc/devices/io-generic.json:2",
			       NULL };
	const char *autostart[] = { "--autostart", NULL };
	/* the devices run before the daemon (and its directory) exists; two
	 * on line 0: a directory each for their control socket and log */
	char dir[32] = "/tmp/mgrt-XXXXXX", dir_b[48];
	TEST_ASSERT_NOT_NULL(mkdtemp(dir));
	snprintf(dir_b, sizeof dir_b, "%s/b", dir);
	TEST_ASSERT_EQUAL_INT(0, mkdir(dir_b, 0700));
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&simA, dir, 0, alive, autostart));
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&simB, dir_b, 0, plain, NULL));
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim1, dir, 1, pair, NULL));
	/* node 1 on line 0 is OPERATIONAL before the manager exists */
	uint8_t hb[8] = { 0 };
	for (uint64_t t = mono_ms() + 5000; hb[0] != 0x05 && mono_ms() < t;)
		(void)can_wait_id(w0.fd, 0x701, hb, 1000);
	TEST_ASSERT_EQUAL_HEX8(0x05, hb[0]);
	watch_reset(&w0);
	watch_drain(&w0);
	watch_reset(&w0); /* only what comes once the daemon runs */
	watch_drain(&w1);
	watch_reset(&w1);

	TEST_ASSERT_EQUAL_INT(0,
			      daemon_start(&dmn, &(daemon_opts){ .config_json = CONFIG_KEEP_RESET,
								 .instance = "mgrt",
								 .n_lines = 2 }));
	TEST_ASSERT_EQUAL_INT(0, cogw_open(&h, "mgrt"));
	TEST_ASSERT_EQUAL_INT(0, cogw_subscribe(h, 1, MBX_EVC_MANAGER, NULL, 0, 3000));

	/* (d) */
	TEST_ASSERT_TRUE_MESSAGE(wait_for(0, &w0, &w1, 30000, both_operational, &st),
				 "line 0 did not boot and start nodes 1 and 2");
	TEST_ASSERT_TRUE_MESSAGE(w0.reset_of[2], "node 2 was not reset at the network boot");
	TEST_ASSERT_TRUE_MESSAGE(w0.bootup_of[2], "node 2 sent no boot-up after its reset");
	TEST_ASSERT_FALSE_MESSAGE(w0.reset_of[1], "the keep-alive node 1 was reset");
	TEST_ASSERT_FALSE_MESSAGE(w0.reset_of[0], "a reset went to all nodes");
	TEST_ASSERT_FALSE_MESSAGE(w0.bootup_of[1], "the keep-alive node 1 rebooted");
	mbx_mgr_node_diag d;
	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_node_diag(h, 0, 1, &d, 3000));
	TEST_ASSERT_EQUAL_UINT8(1, d.booted);
	TEST_ASSERT_EQUAL_UINT32(1, d.boot_count);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_OPERATIONAL, d.nmt_state);

	/* a second device with node 2's ID, plugged in without a boot-up and
	 * without heartbeats: only its SDO answers give it away. A read of
	 * node 2 gets two answers; the manager reports the duplicate. */
	char dir_c[48];
	snprintf(dir_c, sizeof dir_c, "%s/c", dir);
	TEST_ASSERT_EQUAL_INT(0, mkdir(dir_c, 0700));
	const char *twin_args[] = { "--silent", "--hb-stop", NULL };
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&simC, dir_c, 0, plain, twin_args));
	TEST_ASSERT_EQUAL_INT(0, cogw_subscribe(h, 0, MBX_EVC_MANAGER, NULL, 0, 3000));
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&simC, "silent off", NULL, 0, 3000));
	uint32_t v = 0, abort = 0;
	TEST_ASSERT_EQUAL_INT(0, cogw_sdo_read_u32(h, 0, 2, 0x1018, 1, &v, 3000, &abort));
	TEST_ASSERT_EQUAL_HEX32(0x1234, v);
	bool twin = false;
	for (uint64_t t = mono_ms() + 5000; !twin && mono_ms() < t;) {
		if (cogw_recv(h, &m, 200) != 0)
			continue;
		if (m.code == MBX_EV_MGR_NODE && m.line == 0) {
			mbx_ev_mgr e;
			memcpy(&e, m.data, sizeof e);
			twin = e.node == 2 && e.what == CO_MGR_NODE_DUPLICATE &&
			       e.value == CO_MGR_DUP_SDO_ANSWERS;
		}
		cogw_msg_release(&m);
	}
	TEST_ASSERT_TRUE_MESSAGE(twin, "no duplicate event (two SDO answers) for node 2");
	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_status(h, 0, &st, 3000));
	TEST_ASSERT_EQUAL_UINT32(1, st.duplicates);
	cosim_stop(&simC, 3000);

	/* (e) 1F80h bit 4 */
	TEST_ASSERT_TRUE_MESSAGE(wait_for(1, &w0, &w1, 30000, both_operational, &st),
				 "line 1 did not boot and start nodes 1 and 2");
	TEST_ASSERT_EQUAL_UINT32(1, st.network_boots);
	watch_reset(&w1);
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim1, "node 1 hb stop", NULL, 0, 3000));
	for (uint64_t t = mono_ms() + 10000; !w1.reset_cs_all && mono_ms() < t;) {
		sleep_ms(100);
		watch_drain(&w1);
	}
	TEST_ASSERT_EQUAL_HEX8_MESSAGE(0x81, w1.reset_cs_all, "no NMT reset node to all nodes");
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim1, "node 1 hb start", NULL, 0, 3000));
	TEST_ASSERT_TRUE_MESSAGE(wait_for(1, &w0, &w1, 30000, rebooted_after_loss, &st),
				 "line 1 did not boot again after the reset of all nodes");
	TEST_ASSERT_TRUE(w1.bootup_of[1]);
	TEST_ASSERT_TRUE(w1.bootup_of[2]);
	TEST_ASSERT_EQUAL_UINT32(2, st.network_boots);
	/* the reaction was reported: node 1 lost (E), then "reset node" to all */
	bool lost = false, reaction = false;
	while (cogw_recv(h, &m, 200) == 0) {
		if (m.code == MBX_EV_MGR_NODE && m.line == 1) {
			mbx_ev_mgr e;
			memcpy(&e, m.data, sizeof e);
			lost = lost ||
			       (e.node == 1 && e.what == CO_MGR_NODE_LOST && e.value == 'E');
			reaction = reaction ||
				   (e.node == 1 && e.what == CO_MGR_NODE_ERROR_REACTION &&
				    e.value == 0x81);
		}
		cogw_msg_release(&m);
	}
	TEST_ASSERT_TRUE_MESSAGE(lost, "no 'lost' event for node 1");
	TEST_ASSERT_TRUE_MESSAGE(reaction, "no error-reaction event (reset node to all)");
	close(w0.fd);
	close(w1.fd);
	cosim_stop(&simA, 3000);
	cosim_stop(&simB, 3000);
	cosim_stop(&sim1, 3000);
	char rm[64];
	snprintf(rm, sizeof rm, "rm -rf %s", dir);
	TEST_ASSERT_EQUAL_INT(0, system(rm));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_two_lines_boot_identity_request_own_id);
	RUN_TEST(test_ten_devices_missing_mandatory_request_over_sdo_stop_all);
	RUN_TEST(test_keep_alive_not_reset_and_reset_all_on_mandatory_loss);
	return UNITY_END();
}
