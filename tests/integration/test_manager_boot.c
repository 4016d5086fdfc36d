/* SPDX-License-Identifier: MIT */
/*
 * The CiA 302-2 manager in the real daemon on vcan with cosim devices
 * (issue 12 integration items, grouped into one VM boot):
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
 * Run: tests/vcan/run -n 2 -- build/san/tests/integration/test_manager_boot
 */
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "core/manager.h"
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

	/* (h) a device claims the manager's node-ID on line 1 */
	/* its boot-up frame on 77Fh, as a device configured with ID 127 sends */
	int fd = can_open_raw("vcan1");
	TEST_ASSERT_TRUE(fd >= 0);
	uint8_t zero = 0;
	TEST_ASSERT_EQUAL_INT(0, can_send_std(fd, 0x77F, &zero, 1));
	close(fd);
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

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_two_lines_boot_identity_request_own_id);
	RUN_TEST(test_ten_devices_missing_mandatory_request_over_sdo_stop_all);
	return UNITY_END();
}
