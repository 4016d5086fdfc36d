/* SPDX-License-Identifier: MIT */
/*
 * The CiA 302-3 configuration manager (core/cfgmgr.h) plugged into the
 * CiA 302-2 boot process (core/manager.h) as its "configure" step, with
 * simulated slaves on the in-memory bus: a 20-entry concise DCF in 1F22h
 * downloaded during the boot and read back, the node then started; the
 * next boot skips the download because 1020h matches 1F26h/1F27h; an abort
 * on entry 7 ends the boot slave process with J and the entry's
 * index:sub, and the node is not started; restore (1F81h bit 7, 1F8Ah)
 * resets the node inside the configure step without restarting its boot.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/cfgmgr.h"
#include "core/nmt.h"
#include "core/store.h"
#include "tests/unit/support/mgr_fixture.h"
#include "unity.h"

#define MS 1000ull
#define S 1000000ull
#define NODE 2
#define MANDATORY (CO_MGR_1F81_SLAVE | CO_MGR_1F81_BOOT | CO_MGR_1F81_MANDATORY)

static mf f;
static co_cfgmgr_line line;
static co_cfgmgr_result last;
static unsigned results;
static tb_port *slave;
static unsigned restores;

/* The owner's glue, as a line runtime does it: core events to the
 * manager and the configuration manager, the manager's own events kept
 * for the assertions, both timers. */
static void ev_glue(void *ctx, const co_event *ev)
{
	(void)ctx;
	if (ev->kind == CO_EV_MGR_STATE || ev->kind == CO_EV_MGR_BOOT ||
	    ev->kind == CO_EV_MGR_NODE) {
		if (f.n_ev < MF_EVENTS)
			f.ev[f.n_ev++] = *ev;
		if (getenv("MF_TRACE"))
			fprintf(stderr, "%8.3f %s node %u step %s status %c abort %08x %04x:%u\n",
				(double)ev->now_us / 1e6, co_event_kind_to_string(ev->kind),
				ev->u.mgr.node, co_mgr_step_to_string(ev->u.mgr.step),
				ev->u.mgr.status ? ev->u.mgr.status : '-', ev->u.mgr.abort,
				ev->u.mgr.index, ev->u.mgr.sub);
		return;
	}
	if (f.mgr)
		co_manager_on_event(f.mgr, ev);
	co_cfgmgr_line_on_event(&line, ev, ev->now_us);
}

static uint64_t tick_glue(void *ctx, uint64_t now)
{
	(void)ctx;
	uint64_t a = f.mgr ? co_manager_tick(f.mgr, now) : CO_NO_DEADLINE;
	uint64_t b = co_cfgmgr_line_tick(&line, now);
	return a < b ? a : b;
}

static uint64_t deadline_glue(void *ctx)
{
	(void)ctx;
	uint64_t a = f.mgr ? co_manager_next_deadline_us(f.mgr) : CO_NO_DEADLINE;
	uint64_t b = co_cfgmgr_line_next_deadline_us(&line);
	return a < b ? a : b;
}

/* The configuration manager's outcome goes back to the boot process. */
static void cfg_done(void *ctx, const co_cfgmgr_result *r, uint64_t now_us)
{
	(void)ctx;
	last = *r;
	results++;
	co_manager_configure_done(f.mgr, r->node_id,
				  r->outcome == CO_CFGMGR_FAILED_J    ? r->abort
				  : r->outcome == CO_CFGMGR_CANCELLED ? 0x08000000u
								      : 0,
				  r->index, r->sub,
				  r->outcome == CO_CFGMGR_FAILED_J ? r->entry : r->written, now_us);
}

static uint32_t on_restore(void *ctx, uint8_t sub, const co_od_access *a)
{
	(void)ctx;
	(void)sub;
	(void)a;
	restores++;
	return 0;
}

/* "save": what the slave has now becomes what a reset brings back (a
 * device keeps its saved parameters over a reset communication). */
static uint32_t on_save(void *ctx, uint8_t sub, const co_od_access *a)
{
	(void)ctx;
	(void)sub;
	(void)a;
	for (size_t i = 0; co_od_at(slave->od, i); i++) {
		co_od_entry *e = co_od_at(slave->od, i);
		if ((e->access & CO_ACC_WRITE) && !co_type_is_variable((co_type)e->type) &&
		    e->index != 0x1010 && e->index != 0x1011)
			co_od_entry_set_default_raw(e, co_od_entry_raw(e));
	}
	return 0;
}

static const co_store_ops store_ops = { .save = on_save, .restore = on_restore };

void setUp(void)
{
	memset(&line, 0, sizeof line);
	memset(&last, 0, sizeof last);
	results = 0;
	restores = 0;
	mf_init(&f, CO_MGR_1F80_MASTER, 4);
	slave = mf_slave(&f, NODE, 100);
	/* the slave's own objects: 1020h, 2000h..2013h (u16 rw), 1010h/1011h */
	TEST_ASSERT_EQUAL_INT(0,
			      co_od_add_array(slave->od, 0x1020, CO_T_UNSIGNED32, 2, CO_ACC_RW, 0));
	for (uint16_t i = 0; i < 20; i++)
		TEST_ASSERT_EQUAL_INT(0, co_od_add_num(slave->od, (uint16_t)(0x2000 + i), 0,
						       CO_T_UNSIGNED16, CO_ACC_RW, 0, NULL));
	TEST_ASSERT_EQUAL_INT(
		0, co_od_add_num(slave->od, 0x2100, 0, CO_T_UNSIGNED16, CO_ACC_RO, 0, NULL));
	TEST_ASSERT_EQUAL_INT(0, co_store_attach(slave->node, &store_ops, NULL, 3, 1, 1));
	mf_assign(&f, NODE, MANDATORY, 300);
	mf_expect(&f, NODE, MF_DEVICE_TYPE, MF_VENDOR, MF_PRODUCT, MF_REVISION, 1000u + NODE);
	co_od_set_u32(f.mp->od, 0x1F89, 0, 5000);
	TEST_ASSERT_EQUAL_INT(0, co_od_add_cfgmgr_node(f.mp->od, NODE, 4096));
	co_cfgmgr_line_init(&line, f.mp->node, cfg_done, NULL);
	f.mp->ext_event = ev_glue;
	f.mp->ext_tick = tick_glue;
	f.mp->ext_deadline = deadline_glue;
	tb_advance(&f.bus, 10 * MS);
}

void tearDown(void)
{
	co_cfgmgr_line_cancel_all(&line, f.bus.now);
	mf_fini(&f);
}

/* 20 entries 2000h..2013h = 100..119, or with `bad` an entry 7 for the
 * read-only 2100h. Into 1F22h:NODE as over SDO. */
static void put_cdcf(int bad_entry)
{
	uint8_t buf[512];
	co_cdcf_writer w;
	co_cdcf_writer_init(&w, buf, sizeof buf);
	for (unsigned i = 0; i < 20; i++) {
		uint8_t v[2] = { (uint8_t)(100 + i), 0 };
		uint16_t idx = (int)i + 1 == bad_entry ? 0x2100 : (uint16_t)(0x2000 + i);
		TEST_ASSERT_EQUAL_INT(0, co_cdcf_writer_add(&w, idx, 0, v, 2));
	}
	long n = co_cdcf_writer_finish(&w);
	co_od_access a = { .origin = CO_OD_ORIGIN_SDO, .data = buf, .size = (uint32_t)n };
	co_od_entry *e = co_od_find(f.mp->od, 0x1F22, NODE);
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_HEX32(0, co_od_write(e, buf, (uint32_t)n, &a));
}

static uint16_t slave_u16(uint16_t index)
{
	uint16_t v = 0;
	TEST_ASSERT_EQUAL_INT(0, co_od_get_u16(slave->od, index, 0, &v));
	return v;
}

static uint32_t slave_u32(uint16_t index, uint8_t sub)
{
	uint32_t v = 0;
	TEST_ASSERT_EQUAL_INT(0, co_od_get_u32(slave->od, index, sub, &v));
	return v;
}

static void test_boot_downloads_then_skips_when_1020h_matches(void)
{
	put_cdcf(0);
	co_od_set_u32(f.mp->od, 0x1F26, NODE, 15000);
	co_od_set_u32(f.mp->od, 0x1F27, NODE, 3600000);
	line.store[NODE] = true; /* 1020h must survive the next reset communication */
	mf_start(&f, &(co_manager_config){ .sdo_timeout_ms = 200,
					   .configure = co_cfgmgr_line_configure,
					   .configure_ctx = &line });
	tb_advance(&f.bus, 3 * S);

	TEST_ASSERT_EQUAL_UINT(1, results);
	TEST_ASSERT_EQUAL_INT(CO_CFGMGR_CONFIGURED, last.outcome);
	TEST_ASSERT_EQUAL_UINT32(20, last.written);
	for (uint16_t i = 0; i < 20; i++)
		TEST_ASSERT_EQUAL_UINT16(100 + i, slave_u16((uint16_t)(0x2000 + i)));
	TEST_ASSERT_EQUAL_UINT32(15000, slave_u32(0x1020, 1));
	TEST_ASSERT_EQUAL_UINT32(3600000, slave_u32(0x1020, 2));
	TEST_ASSERT_EQUAL_UINT(1, tb_event_count(slave, CO_EV_STORE));
	const co_ev_mgr *e = mf_boot(&f, NODE, CO_MGR_STEP_CONFIGURE, 0);
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_UINT32(20, e->value); /* entries written */
	TEST_ASSERT_NOT_NULL(mf_boot(&f, NODE, CO_MGR_STEP_START, 0));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, co_nmt_get_state(slave->node));
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, co_manager_state(f.mgr));

	/* the next boot of the network: 1020h matches, nothing downloaded */
	for (uint16_t i = 0; i < 20; i++)
		co_od_set_u16(slave->od, (uint16_t)(0x2000 + i), 0, 7);
	TEST_ASSERT_EQUAL_INT(0, co_manager_boot_network(f.mgr, f.bus.now));
	tb_advance(&f.bus, 3 * S);
	TEST_ASSERT_EQUAL_UINT(2, results);
	TEST_ASSERT_EQUAL_INT(CO_CFGMGR_SKIPPED, last.outcome);
	TEST_ASSERT_EQUAL_UINT32(0, last.written);
	e = mf_boot(&f, NODE, CO_MGR_STEP_CONFIGURE, 0);
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_UINT32(0, e->value); /* nothing downloaded */
	/* the reset communication of the new boot does not touch 2000h */
	TEST_ASSERT_EQUAL_UINT16(7, slave_u16(0x2000));
	TEST_ASSERT_NOT_NULL(mf_boot(&f, NODE, CO_MGR_STEP_START, 0));
	TEST_ASSERT_EQUAL(CO_MGR_OPERATIONAL, co_manager_state(f.mgr));
}

static void test_abort_on_entry_7_is_j_and_the_node_is_not_started(void)
{
	put_cdcf(7);
	mf_start(&f, &(co_manager_config){ .sdo_timeout_ms = 200,
					   .configure = co_cfgmgr_line_configure,
					   .configure_ctx = &line });
	tb_advance(&f.bus, 2 * S);

	TEST_ASSERT_TRUE(results >= 1);
	TEST_ASSERT_EQUAL_INT(CO_CFGMGR_FAILED_J, last.outcome);
	TEST_ASSERT_EQUAL_UINT32(7, last.entry);
	TEST_ASSERT_EQUAL_UINT32(6, last.written);
	const co_ev_mgr *e = mf_boot(&f, NODE, CO_MGR_STEP_CONFIGURE, 'J');
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_HEX16(0x2100, e->index);
	TEST_ASSERT_EQUAL_UINT8(0, e->sub);
	TEST_ASSERT_EQUAL_UINT32(7, e->value);          /* the entry number */
	TEST_ASSERT_EQUAL_HEX32(0x06010002, e->abort);  /* read-only object */
	TEST_ASSERT_EQUAL_UINT16(0, slave_u16(0x2007)); /* entry 8 never written */
	TEST_ASSERT_NULL(mf_boot(&f, NODE, CO_MGR_STEP_START, 0));
	TEST_ASSERT_EQUAL_UINT(0, mf_sent(&f, 0x000, "01 02"));
	TEST_ASSERT_NOT_EQUAL(CO_NMT_OPERATIONAL, co_nmt_get_state(slave->node));
	TEST_ASSERT_NOT_EQUAL(CO_MGR_OPERATIONAL, co_manager_state(f.mgr));
}

static void test_restore_inside_the_configure_step(void)
{
	put_cdcf(0);
	co_od_set_u32(f.mp->od, 0x1F81, NODE, MANDATORY | CO_CFGMGR_F81_RESTORE);
	co_od_set_u8(f.mp->od, 0x1F8A, NODE, 1);
	mf_start(&f, &(co_manager_config){ .sdo_timeout_ms = 200,
					   .configure = co_cfgmgr_line_configure,
					   .configure_ctx = &line });
	tb_advance(&f.bus, 4 * S);

	TEST_ASSERT_EQUAL_UINT(1, restores);
	TEST_ASSERT_EQUAL_UINT(1, mf_sent(&f, 0x000, "81 02")); /* reset node, once */
	TEST_ASSERT_EQUAL_UINT(1, results);
	TEST_ASSERT_TRUE(last.restored);
	TEST_ASSERT_EQUAL_INT(CO_CFGMGR_CONFIGURED, last.outcome);
	TEST_ASSERT_EQUAL_UINT16(119, slave_u16(0x2013));
	/* one pass of the boot slave process: its boot-up inside the
	 * configure step did not start it again */
	TEST_ASSERT_EQUAL_UINT(1, mf_boot_count(&f, NODE, CO_MGR_STEP_CONFIGURE, 0));
	TEST_ASSERT_NOT_NULL(mf_boot(&f, NODE, CO_MGR_STEP_START, 0));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, co_nmt_get_state(slave->node));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_boot_downloads_then_skips_when_1020h_matches);
	RUN_TEST(test_abort_on_entry_7_is_j_and_the_node_is_not_started);
	RUN_TEST(test_restore_inside_the_configure_step);
	return UNITY_END();
}
