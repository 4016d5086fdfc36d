/* SPDX-License-Identifier: MIT */
/*
 * Nodes added, changed and removed at run time (docs/config.md "Nodes at
 * run time"), in the real daemon on vcan with cosim devices, one VM boot:
 *   - over the mailbox (libcogw): an I/O module nobody listed is added:
 *     booted, supervised (its heartbeat loss is reported), its PDOs
 *     mirrored; its heartbeat time and PDO layout are changed (a concise
 *     DCF that remaps its TPDO 3); it is removed: no longer assigned,
 *     supervised or reported. The listed node is neither rebooted nor
 *     disturbed.
 *   - bad inputs: an invalid node-ID, the daemon's own node-ID, a node
 *     added twice, a change of a node not listed, a concise DCF that is
 *     not one: each refused with its status and counted.
 *   - cogwctl node add / change / remove.
 *   - SIGHUP with the node added to the file, changed, removed; with a key
 *     that needs a restart changed too, the reload is refused by that
 *     key's JSON path and nothing of the file applies.
 * Run: tests/vcan/run -n 1 -- build/san/tests/integration/test_node_runtime
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/manager.h"
#include "core/nmt.h"
#include "mailbox/cogw.h"
#include "tests/integration/support/daemon.h"
#include "tests/integration/support/proc.h"
#include "unity.h"

#define INSTANCE "nrt"
#define LISTED 1 /* the transducer, in the file from the start */
#define ADDED 2  /* the I/O module, added at run time */

/* One line with a manager, node 1 listed, every PDO mirrored ("auto"). */
#define LINE0(bitrate, nodes)                                                           \
	"{\"version\": 1, \"mailbox\": {\"instance\": \"" INSTANCE "\"}, \"lines\": ["  \
	"{\"interface\": \"vcan0\", \"bitrate\": " bitrate ", \"node_id\": 127, "       \
	"\"pdo\": \"auto\", \"manager\": {\"retry_ms\": 500}, \"nodes\": [{\"id\": 1, " \
	"\"heartbeat_ms\": 2500}" nodes "]}]}"

static daemon_run dmn;
static cosim_run sim1, sim2;
static cogw *h;

void setUp(void)
{
	memset(&dmn, 0, sizeof dmn);
	memset(&sim1, 0, sizeof sim1);
	memset(&sim2, 0, sizeof sim2);
	h = NULL;
}

void tearDown(void)
{
	if (h)
		cogw_close(h);
	cosim_stop(&sim1, 3000);
	cosim_stop(&sim2, 3000);
	daemon_cleanup(&dmn);
	daemon_unlink_queues(INSTANCE);
}

static bool bit(const mbx_mgr_bits *b, unsigned n)
{
	return (b->w[n / 32] >> (n % 32)) & 1u;
}

/* The daemon (notify on: SIGHUP waits for READY=1), both devices, the
 * network operational with node 1 booted and node 2 not listed. */
static void start(const char *config)
{
	mbx_mgr_status st;
	const char *dev1[] = { "etc/devices/sti-pressure.json:1", NULL };
	const char *dev2[] = { "etc/devices/io-generic.json:2", NULL };

	TEST_ASSERT_EQUAL_INT(0, daemon_start(&dmn, &(daemon_opts){ .config_json = config,
								    .instance = INSTANCE,
								    .n_lines = 1,
								    .notify = true }));
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim1, dmn.dir, 0, dev1, NULL));
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim2, dmn.dir, 0, dev2, NULL));
	TEST_ASSERT_EQUAL_INT(0, cogw_open(&h, INSTANCE));
	TEST_ASSERT_EQUAL_INT(0,
			      cogw_subscribe(h, 0, MBX_EVC_BOOT | MBX_EVC_MANAGER, NULL, 0, 3000));
	uint64_t until = mono_ms() + 30000;
	do {
		sleep_ms(100);
		TEST_ASSERT_EQUAL_INT(0, cogw_mgr_status(h, 0, &st, 3000));
	} while ((st.state != CO_MGR_OPERATIONAL || !bit(&st.booted, LISTED)) && mono_ms() < until);
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, st.state);
	TEST_ASSERT_TRUE(bit(&st.booted, LISTED));
	TEST_ASSERT_FALSE(bit(&st.assigned, ADDED));
}

/* Poll the manager until node's bits say `booted` (and assigned) or not. */
static void wait_booted(uint8_t node, bool booted, mbx_mgr_status *st)
{
	uint64_t until = mono_ms() + 20000;
	for (;;) {
		TEST_ASSERT_EQUAL_INT(0, cogw_mgr_status(h, 0, st, 3000));
		if (bit(&st->booted, node) == booted && bit(&st->assigned, node) == booted)
			return;
		TEST_ASSERT_TRUE_MESSAGE(mono_ms() < until,
					 booted ? "node not booted" : "node still assigned");
		sleep_ms(100);
	}
}

/* The 1016h consumer time of node in the daemon's own OD (0 = none). */
static uint16_t consumer_ms(uint8_t node)
{
	for (uint8_t sub = 1; sub <= 127; sub++) {
		uint32_t v = 0;
		size_t len = 0;
		if (cogw_od_read(h, 0, 0x1016, sub, &v, sizeof v, &len, 3000, NULL) != 0)
			return 0;
		if (((v >> 16) & 0xFF) == node && (v & 0xFFFF))
			return (uint16_t)v;
	}
	return 0;
}

/* The next event `code` about node (MGR_NODE: with `what`), else false. */
static bool wait_event(uint16_t code, uint8_t node, int what, int timeout_ms, void *out, size_t len)
{
	uint64_t until = mono_ms() + (uint64_t)timeout_ms;
	cogw_msg m;

	while (mono_ms() < until) {
		if (cogw_recv(h, &m, 200) != 0)
			continue;
		bool hit = m.code == code && m.len >= 1 && m.data[0] == node;
		if (hit && code == MBX_EV_MGR_NODE) {
			mbx_ev_mgr e;
			memcpy(&e, m.data, sizeof e);
			hit = e.what == what;
		}
		if (hit && out)
			memcpy(out, m.data, len < m.len ? len : m.len);
		cogw_msg_release(&m);
		if (hit)
			return true;
	}
	return false;
}

/* A concise DCF: the entries count, then index, sub, size, value (LE). */
typedef struct cdcf {
	uint8_t b[256];
	size_t len;
} cdcf;

static void cdcf_put(cdcf *c, uint16_t index, uint8_t sub, uint32_t size, uint32_t value)
{
	if (!c->len)
		c->len = 4;
	c->b[0]++;
	uint8_t *p = c->b + c->len;
	p[0] = (uint8_t)index;
	p[1] = (uint8_t)(index >> 8);
	p[2] = sub;
	p[3] = (uint8_t)size;
	p[4] = p[5] = p[6] = 0;
	for (uint32_t i = 0; i < size; i++)
		p[7 + i] = (uint8_t)(value >> (8 * i));
	c->len += 7 + size;
}

/* TPDO 3 of the I/O module remapped: its status word out, digital input
 * 1 in (CiA 301 §7.5.2.35/37: invalid, mapping count 0, entries, count,
 * valid again). */
static void remap_tpdo3(cdcf *c)
{
	cdcf_put(c, 0x1802, 1, 4, 0x80000382u);
	cdcf_put(c, 0x1A02, 0, 1, 0);
	cdcf_put(c, 0x1A02, 1, 4, 0x60000108u);
	cdcf_put(c, 0x1A02, 0, 1, 1);
	cdcf_put(c, 0x1802, 1, 4, 0x382u);
}

/* Run cogwctl with args; stdout into out. The exit status. */
static int cogwctl(const char *args, char *out, size_t cap)
{
	char cmd[512];
	snprintf(cmd, sizeof cmd, "build/san/bin/cogwctl --instance " INSTANCE " %s", args);
	return run_capture(cmd, out, cap);
}

/* `cogwctl pdo map 0 NODE` contains text, within a few seconds. */
static bool pdo_map_shows(uint8_t node, const char *text)
{
	char args[32], out[8192];
	snprintf(args, sizeof args, "pdo map 0 %u", node);
	for (uint64_t until = mono_ms() + 10000; mono_ms() < until; sleep_ms(200))
		if (cogwctl(args, out, sizeof out) == 0 && strstr(out, text))
			return true;
	printf("pdo map %u:\n%s\n", node, out);
	return false;
}

static mbx_mgr_node_set_req added_node(uint16_t heartbeat_ms)
{
	return (mbx_mgr_node_set_req){ .node = ADDED,
				       .op = MBX_NODE_ADD,
				       .heartbeat_ms = heartbeat_ms,
				       .pdo = 2,
				       .assignment = CO_MGR_1F81_SLAVE | CO_MGR_1F81_BOOT,
				       .identity = { 0x000F0191u, 0x1234u, 0x401u } };
}

static void test_add_change_remove_over_the_mailbox(void)
{
	mbx_mgr_status st;
	mbx_mgr_node_diag d1;
	mbx_ev_dev_mirror mirror;
	cdcf c = { 0 };

	start(LINE0("1000000", ""));
	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_node_diag(h, 0, LISTED, &d1, 3000));
	uint32_t listed_boots = d1.boot_count;

	/* add: booted, supervised with 1000 ms, its PDOs mirrored */
	cdcf_put(&c, 0x1017, 0, 2, 300);
	mbx_mgr_node_set_req r = added_node(1000);
	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_node_set(h, 0, &r, c.b, c.len, 3000));
	wait_booted(ADDED, true, &st);
	TEST_ASSERT_EQUAL_UINT16(1000, consumer_ms(ADDED));
	TEST_ASSERT_TRUE_MESSAGE(
		wait_event(MBX_EV_DEV_MIRROR, ADDED, 0, 10000, &mirror, sizeof mirror),
		"no mirror event for the added node");
	TEST_ASSERT_TRUE(pdo_map_shows(ADDED, "2100:00 32 bits"));
	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_status(h, 0, &st, 3000));
	TEST_ASSERT_EQUAL_UINT32(1, st.node_changes);

	/* supervised: its heartbeat stops -> lost, reported */
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim2, "hb stop", NULL, 0, 3000));
	TEST_ASSERT_TRUE_MESSAGE(
		wait_event(MBX_EV_MGR_NODE, ADDED, CO_MGR_NODE_LOST, 10000, NULL, 0),
		"the added node's heartbeat loss was not reported");
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim2, "hb start", NULL, 0, 3000));
	TEST_ASSERT_TRUE(wait_event(MBX_EV_MGR_NODE, ADDED, CO_MGR_NODE_BACK, 10000, NULL, 0));

	/* change: heartbeat 1000 -> 2000 ms, TPDO 3 remapped; booted again */
	remap_tpdo3(&c);
	r = added_node(2000);
	r.op = MBX_NODE_CHANGE;
	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_node_set(h, 0, &r, c.b, c.len, 3000));
	TEST_ASSERT_EQUAL_UINT16(2000, consumer_ms(ADDED));
	wait_booted(ADDED, true, &st);
	TEST_ASSERT_TRUE(pdo_map_shows(ADDED, "6000:01  8 bits"));

	/* remove: no longer assigned, supervised or reported */
	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_node_remove(h, 0, ADDED, 3000));
	wait_booted(ADDED, false, &st);
	TEST_ASSERT_EQUAL_UINT16(0, consumer_ms(ADDED));
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim2, "hb stop", NULL, 0, 3000));
	TEST_ASSERT_FALSE_MESSAGE(
		wait_event(MBX_EV_MGR_NODE, ADDED, CO_MGR_NODE_LOST, 3000, NULL, 0),
		"a removed node's heartbeat loss was reported");
	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_status(h, 0, &st, 3000));
	TEST_ASSERT_FALSE(bit(&st.errctrl_lost, ADDED));
	TEST_ASSERT_EQUAL_UINT32(3, st.node_changes);

	/* the listed node went on undisturbed: not booted again */
	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_node_diag(h, 0, LISTED, &d1, 3000));
	TEST_ASSERT_EQUAL_UINT32(listed_boots, d1.boot_count);
	TEST_ASSERT_TRUE(bit(&st.operational, LISTED));
}

static void test_bad_inputs_refused_and_counted(void)
{
	mbx_mgr_status st;
	cdcf c = { 0 };
	mbx_mgr_node_set_req r;

	start(LINE0("1000000", ""));
	/* node-IDs outside 1..127: the mailbox refuses the request itself */
	r = added_node(0);
	r.node = 0;
	TEST_ASSERT_EQUAL_INT(COGW_E_PARAM, cogw_mgr_node_set(h, 0, &r, NULL, 0, 3000));
	r.node = 128;
	TEST_ASSERT_EQUAL_INT(COGW_E_PARAM, cogw_mgr_node_set(h, 0, &r, NULL, 0, 3000));
	/* the daemon's own node-ID */
	r.node = 127;
	TEST_ASSERT_EQUAL_INT(COGW_E_PARAM, cogw_mgr_node_set(h, 0, &r, NULL, 0, 3000));
	/* a duplicate: node 1 is listed */
	r.node = LISTED;
	TEST_ASSERT_EQUAL_INT(COGW_E_STATE, cogw_mgr_node_set(h, 0, &r, NULL, 0, 3000));
	/* a change or removal of a node that is not listed */
	r = added_node(0);
	r.op = MBX_NODE_CHANGE;
	TEST_ASSERT_EQUAL_INT(COGW_E_NOT_FOUND, cogw_mgr_node_set(h, 0, &r, NULL, 0, 3000));
	TEST_ASSERT_EQUAL_INT(COGW_E_NOT_FOUND, cogw_mgr_node_remove(h, 0, ADDED, 3000));
	/* a concise DCF that is not one: 3 entries announced, one there */
	cdcf_put(&c, 0x1017, 0, 2, 300);
	c.b[0] = 3;
	r = added_node(0);
	TEST_ASSERT_EQUAL_INT(COGW_E_PARAM, cogw_mgr_node_set(h, 0, &r, c.b, c.len, 3000));
	/* a heartbeat and a guard time together */
	r = added_node(500);
	r.assignment |= 100u << 16;
	TEST_ASSERT_EQUAL_INT(COGW_E_PARAM, cogw_mgr_node_set(h, 0, &r, NULL, 0, 3000));

	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_status(h, 0, &st, 3000));
	TEST_ASSERT_EQUAL_UINT32(0, st.node_changes);
	/* own node-ID, duplicate, two not found, the bad DCF */
	TEST_ASSERT_EQUAL_UINT32(5, st.node_changes_refused);
	TEST_ASSERT_FALSE(bit(&st.assigned, ADDED));
	mbx_stats_wire ms;
	TEST_ASSERT_EQUAL_INT(0, cogw_mbx_stats(h, 0, &ms, 3000));
	TEST_ASSERT_TRUE(ms.malformed >= 3); /* node 0, node 128, hb with guard */
}

static void test_cogwctl_node(void)
{
	mbx_mgr_status st;
	char out[1024];

	start(LINE0("1000000", ""));
	TEST_ASSERT_EQUAL_INT_MESSAGE(0,
				      cogwctl("node add 0 2 --heartbeat-ms 1500 --vendor-id 0x1234 "
					      "--pdo learn",
					      out, sizeof out),
				      out);
	TEST_ASSERT_NOT_NULL(strstr(out, "line 0: node 2 added"));
	wait_booted(ADDED, true, &st);
	TEST_ASSERT_EQUAL_UINT16(1500, consumer_ms(ADDED));
	TEST_ASSERT_EQUAL_INT(0, cogwctl("node change 0 2 --heartbeat-ms 2500", out, sizeof out));
	TEST_ASSERT_EQUAL_UINT16(2500, consumer_ms(ADDED));
	/* refused: exit status 1, the reason on stderr */
	TEST_ASSERT_EQUAL_INT(1, cogwctl("node add 0 2 2>/dev/null", out, sizeof out));
	TEST_ASSERT_EQUAL_INT(2, cogwctl("node add 0 0 2>/dev/null", out, sizeof out));
	TEST_ASSERT_EQUAL_INT(0, cogwctl("node remove 0 2 --json", out, sizeof out));
	TEST_ASSERT_NOT_NULL(strstr(out, "\"done\":\"removed\""));
	wait_booted(ADDED, false, &st);
}

/* CiA 302-2's own objects: a concise DCF of the manager's entries for
 * node 2 imported into the daemon's OD (1F81h:2 last) adds it; a write of
 * 1F81h:2 = 0 removes it. */
static void test_manager_objects_add_and_remove(void)
{
	mbx_mgr_status st;
	cdcf c = { 0 };
	char path[128], out[1024];

	start(LINE0("1000000", ""));
	cdcf_put(&c, 0x1F85, ADDED, 4, 0x1234);
	cdcf_put(&c, 0x1016, 100, 4, (uint32_t)ADDED << 16 | 1700);
	cdcf_put(&c, 0x1F81, ADDED, 4, CO_MGR_1F81_SLAVE | CO_MGR_1F81_BOOT);
	snprintf(path, sizeof path, "%s/node2.cdc", dmn.dir);
	FILE *f = fopen(path, "wb");
	TEST_ASSERT_NOT_NULL(f);
	TEST_ASSERT_EQUAL_size_t(c.len, fwrite(c.b, 1, c.len, f));
	fclose(f);
	char args[200];
	snprintf(args, sizeof args, "od import 0 %s", path);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, cogwctl(args, out, sizeof out), out);
	TEST_ASSERT_NOT_NULL(strstr(out, "3 entries written"));
	wait_booted(ADDED, true, &st);
	TEST_ASSERT_EQUAL_UINT16(1700, consumer_ms(ADDED));

	/* a wrong vendor expected: its next boot fails with status D */
	TEST_ASSERT_EQUAL_INT(0, cogwctl("od write 0 1F85 2 u32 0x9999", out, sizeof out));
	TEST_ASSERT_EQUAL_INT(0, cogwctl("od write 0 1F81 2 u32 5", out, sizeof out));
	mbx_ev_mgr e = { 0 };
	uint64_t until = mono_ms() + 10000;
	while (e.status != 'D' && mono_ms() < until)
		(void)wait_event(MBX_EV_MGR_BOOT, ADDED, 0, 500, &e, sizeof e);
	TEST_ASSERT_EQUAL('D', e.status);

	TEST_ASSERT_EQUAL_INT(0, cogwctl("od write 0 1F81 2 u32 0", out, sizeof out));
	wait_booted(ADDED, false, &st);
	/* the daemon's own node-ID is no slave of its own */
	TEST_ASSERT_EQUAL_INT(1, cogwctl("od write 0 1F81 127 u32 5 2>/dev/null", out, sizeof out));
}

static void reload_with(const char *json)
{
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, daemon_reload(&dmn, json, 10000),
				      "no RELOADING=1 and READY=1 after SIGHUP");
}

#define NODE2(hb) ", {\"id\": 2, \"heartbeat_ms\": " hb ", \"vendor_id\": \"0x1234\"}"

static void test_sighup_adds_changes_removes(void)
{
	mbx_mgr_status st;
	mbx_mgr_node_diag d1;

	start(LINE0("1000000", ""));
	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_node_diag(h, 0, LISTED, &d1, 3000));
	uint32_t listed_boots = d1.boot_count;

	reload_with(LINE0("1000000", NODE2("1200")));
	TEST_ASSERT_TRUE(
		file_wait_contains(dmn.log_path, "reload: lines[0].nodes[1]: node 2 added", 3000));
	wait_booted(ADDED, true, &st);
	TEST_ASSERT_EQUAL_UINT16(1200, consumer_ms(ADDED));

	reload_with(LINE0("1000000", NODE2("2200")));
	TEST_ASSERT_TRUE(file_wait_contains(dmn.log_path,
					    "reload: lines[0].nodes[1]: node 2 changed", 3000));
	TEST_ASSERT_EQUAL_UINT16(2200, consumer_ms(ADDED));
	wait_booted(ADDED, true, &st);

	/* a key that needs a restart: refused by its path, nothing applied
	 * (node 2's heartbeat stays 2200) */
	reload_with(LINE0("500000", NODE2("3300")));
	TEST_ASSERT_TRUE(file_wait_contains(
		dmn.log_path, "reload refused: lines[0].bitrate: needs a restart", 3000));
	TEST_ASSERT_EQUAL_UINT16(2200, consumer_ms(ADDED));

	reload_with(LINE0("1000000", ""));
	TEST_ASSERT_TRUE(
		file_wait_contains(dmn.log_path, "reload: lines[0].nodes: node 2 removed", 3000));
	wait_booted(ADDED, false, &st);
	TEST_ASSERT_EQUAL_UINT16(0, consumer_ms(ADDED));
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim2, "hb stop", NULL, 0, 3000));
	TEST_ASSERT_FALSE(wait_event(MBX_EV_MGR_NODE, ADDED, CO_MGR_NODE_LOST, 3000, NULL, 0));

	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_node_diag(h, 0, LISTED, &d1, 3000));
	TEST_ASSERT_EQUAL_UINT32(listed_boots, d1.boot_count);
	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_status(h, 0, &st, 3000));
	TEST_ASSERT_EQUAL_UINT32(3, st.node_changes);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_add_change_remove_over_the_mailbox);
	RUN_TEST(test_bad_inputs_refused_and_counted);
	RUN_TEST(test_cogwctl_node);
	RUN_TEST(test_manager_objects_add_and_remove);
	RUN_TEST(test_sighup_adds_changes_removes);
	return UNITY_END();
}
