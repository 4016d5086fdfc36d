/* SPDX-License-Identifier: MIT */
/*
 * The PDO layout step of the CiA 302-2 boot slave process (core/pdo_scan.h
 * plugged in as the manager's pdo_layout hook), with simulated slaves on
 * the in-memory bus: TPDOs of different transmission types and RPDOs read
 * over SDO into the line's table, invalid PDOs skipped without reading
 * their mapping, the first record that does not exist ending a direction,
 * a device that answers an abort (reported, the boot goes on), the room
 * (pdo_scan_max) full (the rest counted as dropped), a remapped device
 * learnt again after its boot-up, nodes that are not scanned.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/cfgmgr.h"
#include "core/nmt.h"
#include "core/pdo.h"
#include "core/pdo_scan.h"
#include "core/sdo.h"
#include "tests/unit/support/mgr_fixture.h"
#include "unity.h"

#define MS 1000ull
#define S 1000000ull
#define NODE 2
#define MANDATORY (CO_MGR_1F81_SLAVE | CO_MGR_1F81_BOOT | CO_MGR_1F81_MANDATORY)

static mf f;
static co_pdo_scan_line line;
static co_pdo_layout *table;
static co_pdo_scan_result last;
static unsigned results;
static tb_port *slave;

static const co_pdo_layout_type types[] = {
	{ 0x2000, 0, 0, CO_T_REAL32 },
	{ 0x6401, 1, 0, CO_T_INTEGER16 },
};

/* The owner's glue, as manager/manager_ext.c does it. */
static void ev_glue(void *ctx, const co_event *ev)
{
	(void)ctx;
	if (ev->kind == CO_EV_MGR_STATE || ev->kind == CO_EV_MGR_BOOT ||
	    ev->kind == CO_EV_MGR_NODE) {
		if (f.n_ev < MF_EVENTS)
			f.ev[f.n_ev++] = *ev;
		return;
	}
	co_pdo_scan_line_on_event(&line, ev, ev->now_us);
	if (f.mgr)
		co_manager_on_event(f.mgr, ev);
}

static uint64_t tick_glue(void *ctx, uint64_t now)
{
	(void)ctx;
	return f.mgr ? co_manager_tick(f.mgr, now) : CO_NO_DEADLINE;
}

static uint64_t deadline_glue(void *ctx)
{
	(void)ctx;
	return f.mgr ? co_manager_next_deadline_us(f.mgr) : CO_NO_DEADLINE;
}

static void scan_done(void *ctx, const co_pdo_scan_result *r, uint64_t now_us)
{
	(void)ctx;
	last = *r;
	results++;
	if (r->outcome == CO_PDO_SCAN_CANCELLED)
		return; /* the node's boot starts again */
	co_manager_pdo_layout_done(
		f.mgr, r->node_id,
		r->outcome == CO_PDO_SCAN_LEARNT ? 0
		: r->abort                       ? r->abort
						 : SDO_AB_GENERAL,
		r->index, r->sub, (uint32_t)r->n[CO_PDO_TX] | r->n[CO_PDO_RX] << 16,
		(uint32_t)r->dropped[CO_PDO_TX] | r->dropped[CO_PDO_RX] << 16, now_us);
}

static void add_pdo(co_pdo_dir dir, uint16_t nr, uint32_t cob, uint8_t tt, uint16_t inhibit,
		    uint16_t event_ms, uint8_t n_map, const uint32_t *map)
{
	co_pdo_desc d = { .dir = dir,
			  .nr = nr,
			  .cob_id = cob,
			  .tt = tt,
			  .inhibit_100us = inhibit,
			  .event_ms = event_ms,
			  .map_subs = 8,
			  .n_map = n_map,
			  .map = map };
	TEST_ASSERT_EQUAL_INT(0, co_od_add_pdo(slave->od, &d));
}

/* TPDO 1 event-driven with inhibit time and event timer, TPDO 2 invalid,
 * TPDO 3 synchronous; RPDO 1 with a dummy byte, RPDO 2 invalid; no
 * record after those (the scan ends at 1803h / 1402h). */
static void device_pdos(void)
{
	static const uint32_t t1[] = { 0x60000108, 0x64010110 }, t2[] = { 0x70000000 },
			      t3[] = { 0x20000020 }, r1[] = { 0x62000108, 0x00050008 },
			      r2[] = { 0x62000108 };
	add_pdo(CO_PDO_TX, 1, 0x180 + NODE, 254, 50, 100, 2, t1);
	add_pdo(CO_PDO_TX, 2, 0x80000280u + NODE, 255, 0, 0, 1, t2);
	add_pdo(CO_PDO_TX, 3, 0x380 + NODE, 1, 0, 0, 1, t3);
	add_pdo(CO_PDO_RX, 1, 0x200 + NODE, 255, 0, 500, 2, r1);
	add_pdo(CO_PDO_RX, 2, 0x80000300u + NODE, 255, 0, 0, 1, r2);
}

static void setup_line(uint16_t cap, bool scan)
{
	uint32_t nodes[4] = { 1u << NODE, 0, 0, 0 };
	TEST_ASSERT_EQUAL_INT(0, co_pdo_layout_create(&table, nodes, cap));
	line.cfg[NODE] = (co_pdo_scan_node){ .scan = scan, .types = types, .n_types = 2 };
	co_pdo_scan_line_init(&line, f.mp->node, table, scan_done, NULL);
	line.sdo_timeout_ms = 100;
}

static void boot(void)
{
	mf_start(&f, &(co_manager_config){ .sdo_timeout_ms = 100,
					   .reset_wait_ms = 500,
					   .pdo_layout = co_pdo_scan_line_step,
					   .pdo_layout_ctx = &line });
	tb_advance(&f.bus, 3 * S);
}

void setUp(void)
{
	memset(&line, 0, sizeof line);
	memset(&last, 0, sizeof last);
	results = 0;
	table = NULL;
	mf_init(&f, CO_MGR_1F80_MASTER, 4);
	slave = mf_slave(&f, NODE, 100);
	mf_assign(&f, NODE, MANDATORY, 300);
	f.mp->ext_event = ev_glue;
	f.mp->ext_tick = tick_glue;
	f.mp->ext_deadline = deadline_glue;
	tb_advance(&f.bus, 10 * MS);
}

void tearDown(void)
{
	co_pdo_scan_line_cancel_all(&line, f.bus.now);
	mf_fini(&f);
	co_pdo_layout_destroy(table);
}

static const co_pdo_layout_node *rec(void)
{
	return co_pdo_layout_node_get(table, NODE);
}

/* SDO upload requests of the manager for index:sub ("40 LL HH SS"). */
static unsigned reads_of(uint16_t index, uint8_t sub)
{
	char hex[16];
	snprintf(hex, sizeof hex, "40 %02X %02X %02X", index & 0xFF, index >> 8, sub);
	return mf_sent(&f, 0x600 + NODE, hex);
}

static void assert_booted(void)
{
	const co_ev_mgr *e = mf_boot(&f, NODE, CO_MGR_STEP_START, 0);
	TEST_ASSERT_NOT_NULL_MESSAGE(e, "the boot did not reach its start step");
	TEST_ASSERT_TRUE(e->done);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_OPERATIONAL, co_manager_node_nmt_state(f.mgr, NODE));
}

static void test_scan_learns_the_devices_pdos(void)
{
	device_pdos();
	setup_line(8, true);
	boot();

	TEST_ASSERT_EQUAL_UINT(1, results);
	TEST_ASSERT_EQUAL_INT(CO_PDO_SCAN_LEARNT, last.outcome);
	TEST_ASSERT_TRUE(rec()->valid);
	TEST_ASSERT_EQUAL_UINT8(CO_PDO_LAYOUT_SCAN, rec()->source);
	TEST_ASSERT_EQUAL_UINT16(2, rec()->n[CO_PDO_TX]);
	TEST_ASSERT_EQUAL_UINT16(1, rec()->n[CO_PDO_RX]);
	TEST_ASSERT_EQUAL_UINT16(1, last.invalid[CO_PDO_TX]);
	TEST_ASSERT_EQUAL_UINT16(1, last.invalid[CO_PDO_RX]);

	const co_pdo_layout_pdo *t1 = &rec()->pdo[CO_PDO_TX][0];
	TEST_ASSERT_EQUAL_UINT16(1, t1->nr);
	TEST_ASSERT_EQUAL_HEX32(0x182, t1->cob);
	TEST_ASSERT_EQUAL_UINT8(254, t1->tt);
	TEST_ASSERT_EQUAL_UINT16(50, t1->inhibit);
	TEST_ASSERT_EQUAL_UINT16(100, t1->event_ms);
	TEST_ASSERT_EQUAL_UINT8(2, t1->n);
	TEST_ASSERT_EQUAL_UINT8(3, t1->bytes);
	TEST_ASSERT_EQUAL_HEX16(0x6000, t1->map[0].index);
	TEST_ASSERT_EQUAL_UINT16(0, t1->map[0].type); /* SDO cannot tell */
	TEST_ASSERT_EQUAL_HEX16(0x6401, t1->map[1].index);
	TEST_ASSERT_EQUAL_UINT8(8, t1->map[1].offset);
	TEST_ASSERT_EQUAL_UINT16(CO_T_INTEGER16, t1->map[1].type); /* the type list */

	const co_pdo_layout_pdo *t3 = &rec()->pdo[CO_PDO_TX][1];
	TEST_ASSERT_EQUAL_UINT16(3, t3->nr);
	TEST_ASSERT_EQUAL_UINT8(1, t3->tt);
	TEST_ASSERT_EQUAL_UINT16(CO_T_REAL32, t3->map[0].type);

	const co_pdo_layout_pdo *r1 = &rec()->pdo[CO_PDO_RX][0];
	TEST_ASSERT_EQUAL_HEX32(0x202, r1->cob);
	TEST_ASSERT_EQUAL_UINT16(500, r1->event_ms);               /* its deadline */
	TEST_ASSERT_EQUAL_UINT16(CO_T_UNSIGNED8, r1->map[1].type); /* dummy 0005h */
	TEST_ASSERT_EQUAL_UINT8(2, r1->bytes);

	/* invalid PDOs: COB-ID only; the end of each direction: one read */
	TEST_ASSERT_EQUAL_UINT(1, reads_of(0x1801, 1));
	TEST_ASSERT_EQUAL_UINT(0, reads_of(0x1A01, 0));
	TEST_ASSERT_EQUAL_UINT(0, reads_of(0x1601, 0));
	TEST_ASSERT_EQUAL_UINT(1, reads_of(0x1803, 1));
	TEST_ASSERT_EQUAL_UINT(0, reads_of(0x1804, 1));
	TEST_ASSERT_EQUAL_UINT(1, reads_of(0x1402, 1));
	/* an RPDO has no inhibit time or SYNC start to read */
	TEST_ASSERT_EQUAL_UINT(0, reads_of(0x1400, 3));
	TEST_ASSERT_EQUAL_UINT(1, reads_of(0x1800, 6));

	/* the boot event reports it, then the boot goes on */
	const co_ev_mgr *e = mf_boot(&f, NODE, CO_MGR_STEP_PDO_LAYOUT, 0);
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_HEX32(0, e->abort);
	TEST_ASSERT_EQUAL_HEX32(2u | 1u << 16, e->value);
	TEST_ASSERT_EQUAL_HEX32(0, e->expected);
	TEST_ASSERT_EQUAL_STRING("pdo-layout", co_mgr_step_to_string(CO_MGR_STEP_PDO_LAYOUT));
	assert_booted();
}

static void test_room_full_counts_the_rest_as_dropped(void)
{
	device_pdos();
	setup_line(1, true);
	boot();

	TEST_ASSERT_EQUAL_INT(CO_PDO_SCAN_LEARNT, last.outcome);
	TEST_ASSERT_EQUAL_UINT16(1, rec()->n[CO_PDO_TX]);
	TEST_ASSERT_EQUAL_UINT16(1, rec()->dropped[CO_PDO_TX]);
	TEST_ASSERT_EQUAL_UINT16(1, rec()->n[CO_PDO_RX]);
	TEST_ASSERT_EQUAL_UINT16(0, rec()->dropped[CO_PDO_RX]);
	TEST_ASSERT_EQUAL_UINT(0, reads_of(0x1A02, 0)); /* not kept: not read */
	const co_ev_mgr *e = mf_boot(&f, NODE, CO_MGR_STEP_PDO_LAYOUT, 0);
	TEST_ASSERT_EQUAL_HEX32(1u | 1u << 16, e->value);
	TEST_ASSERT_EQUAL_HEX32(1u, e->expected);
	assert_booted();
}

static uint32_t refuse_read(void *ctx, co_od_entry *e, const co_od_access *a)
{
	(void)ctx;
	(void)e;
	(void)a;
	return SDO_AB_WRITE_ONLY;
}

static const co_od_hooks refusing = { .read = refuse_read };

/* A device answering an abort on 1800h:2: reported with the object, the
 * layout stays invalid, the boot goes on. */
static void test_an_abort_is_reported_and_the_boot_goes_on(void)
{
	device_pdos();
	co_od_entry_set_hooks(co_od_find(slave->od, 0x1800, 2), &refusing, NULL);
	setup_line(8, true);
	boot();

	TEST_ASSERT_EQUAL_INT(CO_PDO_SCAN_ABORTED, last.outcome);
	TEST_ASSERT_FALSE(rec()->valid);
	const co_ev_mgr *e = mf_boot(&f, NODE, CO_MGR_STEP_PDO_LAYOUT, 0);
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_WRITE_ONLY, e->abort);
	TEST_ASSERT_EQUAL_HEX16(0x1800, e->index);
	TEST_ASSERT_EQUAL_UINT8(2, e->sub);
	TEST_ASSERT_EQUAL_UINT(0, mf_boot_count(&f, NODE, -1, 'J'));
	assert_booted();
}

/* A valid PDO without its mapping record: 06020000h there is no end of
 * the walk but an abort. */
static void test_a_missing_mapping_record_is_an_abort(void)
{
	TEST_ASSERT_EQUAL_INT(
		0, co_od_add_num(slave->od, 0x1800, 1, CO_T_UNSIGNED32, CO_ACC_RW, 0x182, NULL));
	TEST_ASSERT_EQUAL_INT(
		0, co_od_add_num(slave->od, 0x1800, 2, CO_T_UNSIGNED8, CO_ACC_RW, 254, NULL));
	setup_line(8, true);
	boot();

	TEST_ASSERT_EQUAL_INT(CO_PDO_SCAN_ABORTED, last.outcome);
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_NO_OBJ, last.abort);
	TEST_ASSERT_EQUAL_HEX16(0x1A00, last.index);
	assert_booted();
}

/* A device without PDOs: one read per direction, an empty valid layout. */
static void test_no_pdos_at_all(void)
{
	setup_line(8, true);
	boot();

	TEST_ASSERT_EQUAL_INT(CO_PDO_SCAN_LEARNT, last.outcome);
	TEST_ASSERT_TRUE(rec()->valid);
	TEST_ASSERT_EQUAL_UINT16(0, rec()->n[CO_PDO_TX]);
	TEST_ASSERT_EQUAL_UINT(1, reads_of(0x1800, 1));
	TEST_ASSERT_EQUAL_UINT(1, reads_of(0x1400, 1));
	assert_booted();
}

/* The device is remapped and reboots: its layout is invalid from the
 * boot-up on, and the next boot learns the new one. */
static void test_remapped_device_is_learnt_again_after_its_boot_up(void)
{
	device_pdos();
	setup_line(8, true);
	boot();
	TEST_ASSERT_TRUE(rec()->valid);
	uint32_t gen = rec()->generation;

	/* TPDO 1 now maps 6401:01 alone, TPDO 2 becomes valid */
	TEST_ASSERT_EQUAL_HEX32(0, tb_od_write(&f.bus, slave->node, 0x1A00, 0, 0));
	TEST_ASSERT_EQUAL_HEX32(0, tb_od_write(&f.bus, slave->node, 0x1A00, 1, 0x64010110));
	TEST_ASSERT_EQUAL_HEX32(0, tb_od_write(&f.bus, slave->node, 0x1A00, 0, 1));
	TEST_ASSERT_EQUAL_HEX32(0, tb_od_write(&f.bus, slave->node, 0x1A01, 1, 0x60000108));
	TEST_ASSERT_EQUAL_HEX32(0, tb_od_write(&f.bus, slave->node, 0x1801, 1, 0x282));
	/* a boot-up event alone invalidates it */
	co_event up = { .kind = CO_EV_BOOTUP, .now_us = f.bus.now };
	up.u.errctrl.node = NODE;
	co_pdo_scan_line_on_event(&line, &up, f.bus.now);
	TEST_ASSERT_FALSE(rec()->valid);
	TEST_ASSERT_EQUAL_UINT32(gen + 1, rec()->generation);
	co_pdo_layout_commit(table, NODE, f.bus.now); /* as it was */
	gen = rec()->generation;

	/* its boot-up on the bus: invalidated, scanned again, committed (the
	 * simulated device answers at once) */
	tb_send_hex(&f.bus, 0x700 + NODE, "00");
	tb_advance(&f.bus, 3 * S);
	TEST_ASSERT_EQUAL_UINT32(gen + 3, rec()->generation);
	TEST_ASSERT_EQUAL_UINT(2, results);
	TEST_ASSERT_TRUE(rec()->valid);
	TEST_ASSERT_EQUAL_UINT16(3, rec()->n[CO_PDO_TX]);
	TEST_ASSERT_EQUAL_UINT8(1, rec()->pdo[CO_PDO_TX][0].n);
	TEST_ASSERT_EQUAL_HEX16(0x6401, rec()->pdo[CO_PDO_TX][0].map[0].index);
	TEST_ASSERT_EQUAL_UINT16(2, rec()->pdo[CO_PDO_TX][1].nr);
	TEST_ASSERT_EQUAL_HEX32(0x282, rec()->pdo[CO_PDO_TX][1].cob);
	TEST_ASSERT_EQUAL_UINT(2, mf_boot_count(&f, NODE, CO_MGR_STEP_PDO_LAYOUT, 0));
}

static unsigned dropped_answers;

/* The device's answer to the read of 1A00h:1 is lost, once. */
static tb_action lose_1a00_1(void *ctx, const co_frame *fr, int from, uint64_t n)
{
	(void)ctx;
	(void)from;
	(void)n;
	if (fr->id == 0x580 + NODE && fr->data[1] == 0x00 && fr->data[2] == 0x1A &&
	    fr->data[3] == 1 && !dropped_answers++)
		return TB_DROP;
	return TB_DELIVER;
}

/* A boot-up while the scan waits for an answer: the scan is cancelled
 * without a report (the node's boot starts again), its late answer is
 * ignored, and the new boot learns the layout. */
static void test_a_boot_up_during_the_scan_cancels_it(void)
{
	device_pdos();
	setup_line(8, true);
	dropped_answers = 0;
	f.bus.filter = lose_1a00_1;
	mf_start(&f, &(co_manager_config){ .sdo_timeout_ms = 100,
					   .reset_wait_ms = 500,
					   .pdo_layout = co_pdo_scan_line_step,
					   .pdo_layout_ctx = &line });
	for (int i = 0; i < 2000 && !dropped_answers; i++)
		tb_advance(&f.bus, 1 * MS);
	TEST_ASSERT_EQUAL_UINT(1, dropped_answers);
	TEST_ASSERT_TRUE(co_pdo_scan_running(&line.job[NODE - 1]));

	tb_send_hex(&f.bus, 0x700 + NODE, "00");
	tb_advance(&f.bus, 3 * S);
	TEST_ASSERT_EQUAL_UINT(2, results);
	TEST_ASSERT_EQUAL_INT(CO_PDO_SCAN_LEARNT, last.outcome);
	TEST_ASSERT_TRUE(rec()->valid);
	TEST_ASSERT_EQUAL_UINT16(2, rec()->n[CO_PDO_TX]);
	/* one report: the learnt layout, none for the cancelled scan */
	TEST_ASSERT_EQUAL_UINT(1, mf_boot_count(&f, NODE, CO_MGR_STEP_PDO_LAYOUT, -1));
	TEST_ASSERT_EQUAL_HEX32(0, mf_boot(&f, NODE, CO_MGR_STEP_PDO_LAYOUT, -1)->abort);
	assert_booted();
}

/* The node's boot asked for again while its scan waits for an answer:
 * the pool runs the node's requests in order, so the old scan ends (its
 * read times out) before the new boot's reads; its end does not reach the
 * new boot, which scans afresh and reports once. */
static void test_a_boot_request_during_the_scan_scans_afresh(void)
{
	device_pdos();
	setup_line(8, true);
	dropped_answers = 0;
	f.bus.filter = lose_1a00_1;
	mf_start(&f, &(co_manager_config){ .sdo_timeout_ms = 100,
					   .reset_wait_ms = 500,
					   .pdo_layout = co_pdo_scan_line_step,
					   .pdo_layout_ctx = &line });
	for (int i = 0; i < 2000 && !dropped_answers; i++)
		tb_advance(&f.bus, 1 * MS);
	TEST_ASSERT_EQUAL_UINT(1, dropped_answers);

	TEST_ASSERT_EQUAL_INT(0, co_manager_boot_node(f.mgr, NODE, f.bus.now));
	tb_advance(&f.bus, 3 * S);
	TEST_ASSERT_EQUAL_INT(CO_PDO_SCAN_LEARNT, last.outcome);
	TEST_ASSERT_TRUE(rec()->valid);
	TEST_ASSERT_EQUAL_UINT16(2, rec()->n[CO_PDO_TX]);
	TEST_ASSERT_EQUAL_UINT8(2, rec()->pdo[CO_PDO_TX][0].n);
	TEST_ASSERT_EQUAL_UINT(1, mf_boot_count(&f, NODE, CO_MGR_STEP_PDO_LAYOUT, -1));
	TEST_ASSERT_EQUAL_HEX32(0, mf_boot(&f, NODE, CO_MGR_STEP_PDO_LAYOUT, -1)->abort);
	assert_booted();
}

/* pdo off, or a file layout whose concise DCF (1F22h:n) is unchanged:
 * no read, no event, the file layout stays valid. */
static void test_nodes_that_are_not_scanned(void)
{
	device_pdos();
	setup_line(8, false);
	boot();
	TEST_ASSERT_EQUAL_UINT(0, results);
	TEST_ASSERT_EQUAL_UINT(0, reads_of(0x1800, 1));
	TEST_ASSERT_EQUAL_UINT(0, mf_boot_count(&f, NODE, CO_MGR_STEP_PDO_LAYOUT, -1));
	assert_booted();
}

static void test_file_layout_holds_until_its_configuration_changes(void)
{
	static const uint8_t cdcf[] = { 1, 0, 0, 0, 0x17, 0x10, 0, 2, 0, 0, 0, 0xE8, 0x03 };
	device_pdos();
	TEST_ASSERT_EQUAL_INT(0, co_od_add_cfgmgr_node(f.mp->od, NODE, 64));
	co_od_entry *e = co_od_find(f.mp->od, 0x1F22, NODE);
	co_od_access a = { .origin = CO_OD_ORIGIN_SDO, .data = cdcf, .size = sizeof cdcf };
	TEST_ASSERT_EQUAL_HEX32(0, co_od_write(e, cdcf, sizeof cdcf, &a));
	uint32_t nodes[4] = { 1u << NODE, 0, 0, 0 };
	TEST_ASSERT_EQUAL_INT(0, co_pdo_layout_create(&table, nodes, 8));
	co_pdo_layout_begin(table, NODE, CO_PDO_LAYOUT_FILE);
	co_pdo_layout_commit(table, NODE, 1);
	line.cfg[NODE] = (co_pdo_scan_node){ .from_file = true, .scan_if_reconfigured = true };
	co_pdo_scan_line_init(&line, f.mp->node, table, scan_done, NULL);
	boot();
	TEST_ASSERT_EQUAL_UINT(0, results);
	TEST_ASSERT_TRUE(rec()->valid);
	TEST_ASSERT_EQUAL_UINT8(CO_PDO_LAYOUT_FILE, rec()->source);

	/* a new concise DCF, then a boot: the file no longer describes it */
	static const uint8_t other[] = { 1, 0, 0, 0, 0x17, 0x10, 0, 2, 0, 0, 0, 0xD0, 0x07 };
	a.data = other;
	TEST_ASSERT_EQUAL_HEX32(0, co_od_write(e, other, sizeof other, &a));
	TEST_ASSERT_EQUAL_INT(0, co_manager_boot_node(f.mgr, NODE, f.bus.now));
	tb_advance(&f.bus, 3 * S);
	TEST_ASSERT_EQUAL_UINT(1, results);
	TEST_ASSERT_TRUE(rec()->valid);
	TEST_ASSERT_EQUAL_UINT8(CO_PDO_LAYOUT_SCAN, rec()->source);
	TEST_ASSERT_EQUAL_UINT16(2, rec()->n[CO_PDO_TX]);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_scan_learns_the_devices_pdos);
	RUN_TEST(test_room_full_counts_the_rest_as_dropped);
	RUN_TEST(test_an_abort_is_reported_and_the_boot_goes_on);
	RUN_TEST(test_a_missing_mapping_record_is_an_abort);
	RUN_TEST(test_no_pdos_at_all);
	RUN_TEST(test_remapped_device_is_learnt_again_after_its_boot_up);
	RUN_TEST(test_a_boot_up_during_the_scan_cancels_it);
	RUN_TEST(test_a_boot_request_during_the_scan_scans_afresh);
	RUN_TEST(test_nodes_that_are_not_scanned);
	RUN_TEST(test_file_layout_holds_until_its_configuration_changes);
	return UNITY_END();
}
