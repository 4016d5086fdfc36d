/* SPDX-License-Identifier: MIT */
/*
 * core/cfgmgr: the CiA 302-3 configuration download of one slave, with a
 * manager core and a simulated slave core on the in-memory bus: entries
 * written in order in the mode their size needs and read back from the
 * slave's OD; the first abort stops it with J, entry number, index:sub and
 * abort code; verify configuration via 1020h (skip, mismatch, 1020h
 * missing); 1020h written and 1010h stored after a download; restore
 * (1011h "load", reset, boot-up) and a slave that never comes back;
 * cancel, a held channel and the pool.
 */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "unity.h"

#include "core/cdcf.h"
#include "core/cfgmgr.h"
#include "core/co.h"
#include "core/nmt.h"
#include "core/sdo.h"
#include "core/store.h"
#include "tests/unit/support/test_bus.h"
#include "tests/unit/support/test_od_fixture.h"

#define SLAVE 5

static tb_bus bus;
static tb_port *mgr, *slv;
static co_cfgmgr job;
static co_cfgmgr_result res;
static unsigned done_calls;
static size_t ev_seen;
static uint8_t cdcf[4096];
static size_t cdcf_len;
static co_cdcf_writer w;
static unsigned restores;
static co_cfgmgr_line line;

static uint32_t on_restore(void *ctx, uint8_t sub, const co_od_access *a)
{
	(void)ctx;
	(void)sub;
	(void)a;
	restores++;
	return 0;
}

static const co_store_ops store_ops = { .restore = on_restore };

static void on_done(void *ctx, const co_cfgmgr_result *r, uint64_t now_us)
{
	(void)ctx;
	(void)now_us;
	res = *r;
	done_calls++;
}

void setUp(void)
{
	co_node_config scfg = { .node_id = SLAVE };
	co_node_config mcfg = { .node_id = 1,
				.sdo_client_count = 2,
				.sdo_client_block_threshold = 64 };
	co_od *sod = fx_od_new(), *mod;

	tb_init(&bus);
	TEST_ASSERT_EQUAL_INT(0, co_od_add_array(sod, 0x1020, CO_T_UNSIGNED32, 2, CO_ACC_RW, 0));
	/* TPDO 1 mapping (the fixture has its communication record only) */
	TEST_ASSERT_EQUAL_INT(
		0, co_od_ensure_num(sod, 0x1A00, 0, CO_T_UNSIGNED8, CO_ACC_RW, 0, CO_OBJ_RECORD));
	for (uint8_t s = 1; s <= 8; s++)
		TEST_ASSERT_EQUAL_INT(0, co_od_ensure_num(sod, 0x1A00, s, CO_T_UNSIGNED32,
							  CO_ACC_RW, 0, CO_OBJ_RECORD));
	slv = tb_add_node(&bus, &scfg, sod);
	TEST_ASSERT_NOT_NULL(slv);
	TEST_ASSERT_EQUAL_INT(0, co_store_attach(slv->node, &store_ops, NULL, 3, CO_STORE_CAP_CMD,
						 CO_STORE_CAP_CMD));
	TEST_ASSERT_EQUAL_INT(0, co_od_create(&mod, 16));
	mgr = tb_add_node(&bus, &mcfg, mod);
	TEST_ASSERT_NOT_NULL(mgr);
	tb_settle(&bus, 100000);
	tb_events_clear(mgr);
	tb_events_clear(slv);
	memset(&job, 0, sizeof job);
	memset(&res, 0, sizeof res);
	done_calls = 0;
	ev_seen = 0;
	restores = 0;
	co_cdcf_writer_init(&w, cdcf, sizeof cdcf);
}

void tearDown(void)
{
	if (co_cfgmgr_running(&job))
		co_cfgmgr_cancel(&job, bus.now);
	if (line.node)
		co_cfgmgr_line_cancel_all(&line, bus.now);
	memset(&line, 0, sizeof line);
	tb_fini(&bus);
}

static void add(uint16_t index, uint8_t sub, const void *data, uint32_t size)
{
	TEST_ASSERT_EQUAL_INT(0, co_cdcf_writer_add(&w, index, sub, data, size));
}

static void add_u(uint16_t index, uint8_t sub, uint64_t v, uint32_t size)
{
	uint8_t b[8];
	for (uint32_t i = 0; i < size; i++)
		b[i] = (uint8_t)(v >> (8 * i));
	add(index, sub, b, size);
}

static void finish_cdcf(void)
{
	long n = co_cdcf_writer_finish(&w);
	TEST_ASSERT_TRUE(n > 0);
	cdcf_len = (size_t)n;
}

static co_cfgmgr_params params(void)
{
	co_cfgmgr_params p = {
		.node_id = SLAVE, .cdcf = cdcf, .cdcf_len = cdcf_len, .channel = 0, .done = on_done
	};
	return p;
}

/* Forward the manager's new events to the job, run its timer, move time. */
static void drive(uint64_t limit_us)
{
	uint64_t end = bus.now + limit_us;

	while (!done_calls && bus.now < end) {
		tb_pump(&bus);
		for (; ev_seen < mgr->n_ev; ev_seen++)
			co_cfgmgr_on_event(&job, &mgr->ev[ev_seen], bus.now);
		co_cfgmgr_tick(&job, bus.now);
		tb_advance(&bus, 1000);
	}
	tb_settle(&bus, 10000);
}

static void start(const co_cfgmgr_params *p)
{
	TEST_ASSERT_EQUAL_INT(0, co_cfgmgr_start(&job, mgr->node, p, bus.now));
	TEST_ASSERT_EQUAL_UINT(0, done_calls); /* never from inside start */
	drive(20000000);
	TEST_ASSERT_EQUAL_UINT_MESSAGE(1, done_calls, "the job did not end");
}

static uint64_t slave_u(uint16_t index, uint8_t sub)
{
	uint64_t v = 0;
	TEST_ASSERT_EQUAL_INT(0, co_od_get_u64(slv->od, index, sub, &v));
	return v;
}

/* SDO requests of the manager completed since event index `since`. */
static size_t requests(size_t since)
{
	size_t n = 0;
	for (size_t i = since; i < mgr->n_ev; i++)
		n += mgr->ev[i].kind == CO_EV_SDO_CLIENT_DONE;
	return n;
}

/* A 20-entry configuration: PDO remapping, heartbeat, parameters, a
 * string and a domain (expedited, segmented and block downloads). */
static void twenty_entries(uint8_t *domain, uint32_t dsize)
{
	add_u(0x1800, 1, 0x80000185u, 4);               /* 1: TPDO invalid */
	add_u(0x1800, 2, 254, 1);                       /* 2 */
	add_u(0x1800, 3, 100, 2);                       /* 3: inhibit 10 ms */
	add_u(0x1800, 5, 500, 2);                       /* 4: event timer */
	add_u(0x1A00, 0, 0, 1);                         /* 5 */
	add_u(0x1A00, 1, 0x20030020u, 4);               /* 6 */
	add_u(0x1A00, 0, 1, 1);                         /* 7 */
	add_u(0x1800, 1, 0x185u, 4);                    /* 8: valid again */
	add_u(0x1017, 0, 250, 2);                       /* 9: heartbeat */
	add_u(FX_IDX_LIMITED, 0, 500, 2);               /* 10 */
	add_u(FX_IDX_SIGNED, 0, (uint16_t)-50, 2);      /* 11 */
	add_u(FX_IDX_BOOL, 0, 1, 1);                    /* 12 */
	add_u(FX_IDX_U64, 0, 0x1122334455667788ull, 8); /* 13: segmented */
	add(FX_IDX_STR, 0, "configured by cogw", 18);   /* 14: segmented */
	add_u(FX_IDX_WO, 0, 7, 1);                      /* 15 */
	add_u(FX_IDX_HOOKED, 0, 0xDEADBEEFu, 4);        /* 16 */
	add_u(0x1017, 0, 300, 2);                       /* 17: the last value wins */
	add(FX_IDX_DOMAIN, 0, domain, dsize);           /* 18: block */
	add_u(FX_IDX_LIMITED, 0, 999, 2);               /* 19 */
	add_u(FX_IDX_SIGNED, 0, 42, 2);                 /* 20 */
	finish_cdcf();
}

static void test_twenty_entries_downloaded_in_order_and_read_back(void)
{
	static uint8_t domain[1500];
	for (size_t i = 0; i < sizeof domain; i++)
		domain[i] = (uint8_t)(i * 7 + 3);
	twenty_entries(domain, sizeof domain);
	size_t ev0 = mgr->n_ev;
	co_cfgmgr_params p = params();
	start(&p);

	char why[96];
	snprintf(why, sizeof why, "entry %u %04X:%02X abort %08X", (unsigned)res.entry, res.index,
		 res.sub, (unsigned)res.abort);
	TEST_ASSERT_EQUAL_INT_MESSAGE(CO_CFGMGR_CONFIGURED, res.outcome, why);
	TEST_ASSERT_EQUAL_INT(0, res.status);
	TEST_ASSERT_EQUAL_UINT32(20, res.written);
	TEST_ASSERT_EQUAL_UINT(20, requests(ev0)); /* nothing else: no verify, no store */
	TEST_ASSERT_EQUAL_STRING("done", co_cfgmgr_state_to_string(co_cfgmgr_state_of(&job)));

	TEST_ASSERT_EQUAL_HEX64(0x185, slave_u(0x1800, 1));
	TEST_ASSERT_EQUAL_UINT64(254, slave_u(0x1800, 2));
	TEST_ASSERT_EQUAL_UINT64(100, slave_u(0x1800, 3));
	TEST_ASSERT_EQUAL_UINT64(500, slave_u(0x1800, 5));
	TEST_ASSERT_EQUAL_UINT64(1, slave_u(0x1A00, 0));
	TEST_ASSERT_EQUAL_HEX64(0x20030020u, slave_u(0x1A00, 1));
	TEST_ASSERT_EQUAL_UINT64(300, slave_u(0x1017, 0));
	TEST_ASSERT_EQUAL_UINT64(999, slave_u(FX_IDX_LIMITED, 0));
	TEST_ASSERT_EQUAL_UINT64(42, slave_u(FX_IDX_SIGNED, 0));
	TEST_ASSERT_EQUAL_HEX64(0x1122334455667788ull, slave_u(FX_IDX_U64, 0));
	TEST_ASSERT_EQUAL_HEX64(0xDEADBEEFu, slave_u(FX_IDX_HOOKED, 0));
	char s[64];
	uint32_t len = 0;
	TEST_ASSERT_EQUAL_INT(0, co_od_get_bytes(slv->od, FX_IDX_STR, 0, s, sizeof s, &len));
	TEST_ASSERT_EQUAL_UINT32(18, len);
	TEST_ASSERT_EQUAL_MEMORY("configured by cogw", s, 18);
	static uint8_t back[sizeof domain];
	TEST_ASSERT_EQUAL_INT(0,
			      co_od_get_bytes(slv->od, FX_IDX_DOMAIN, 0, back, sizeof back, &len));
	TEST_ASSERT_EQUAL_UINT32(sizeof domain, len);
	TEST_ASSERT_EQUAL_MEMORY(domain, back, sizeof domain);

	/* each entry with the mode its size needs */
	unsigned exp = 0, seg = 0, blk = 0;
	for (size_t i = 0; i < mgr->n_ev; i++) {
		const co_event *e = &mgr->ev[i];
		if (e->kind != CO_EV_SDO_CLIENT_DONE)
			continue;
		exp += e->u.sdo_cli.mode == SDO_MODE_EXPEDITED;
		seg += e->u.sdo_cli.mode == SDO_MODE_SEGMENTED;
		blk += e->u.sdo_cli.mode == SDO_MODE_BLOCK;
		if (e->u.sdo_cli.index == FX_IDX_DOMAIN)
			TEST_ASSERT_EQUAL_INT(SDO_MODE_BLOCK, e->u.sdo_cli.mode);
	}
	TEST_ASSERT_EQUAL_UINT(17, exp);
	TEST_ASSERT_EQUAL_UINT(2, seg);
	TEST_ASSERT_EQUAL_UINT(1, blk);
}

static void test_first_abort_stops_with_j(void)
{
	add_u(0x1017, 0, 100, 2);         /* 1 */
	add_u(FX_IDX_LIMITED, 0, 500, 2); /* 2 */
	add_u(FX_IDX_BOOL, 0, 1, 1);      /* 3 */
	add_u(0x1800, 5, 77, 2);          /* 4 */
	add_u(FX_IDX_SIGNED, 0, 5, 2);    /* 5 */
	add_u(0x1800, 2, 1, 1);           /* 6 */
	add_u(FX_IDX_LIMITED, 0, 5, 2);   /* 7: below the limit 10 */
	add_u(0x1017, 0, 900, 2);         /* 8: never written */
	finish_cdcf();
	size_t ev0 = mgr->n_ev;
	co_cfgmgr_params p = params();
	p.verify = true; /* 1020h is not read again after a failure */
	p.date = 1;
	p.time = 2;
	p.store = true;
	start(&p);

	TEST_ASSERT_EQUAL_INT(CO_CFGMGR_FAILED_J, res.outcome);
	TEST_ASSERT_EQUAL_INT('J', res.status);
	TEST_ASSERT_EQUAL_UINT32(7, res.entry);
	TEST_ASSERT_EQUAL_HEX16(FX_IDX_LIMITED, res.index);
	TEST_ASSERT_EQUAL_HEX8(0, res.sub);
	TEST_ASSERT_EQUAL_HEX32(0x06090032, res.abort); /* value too low */
	TEST_ASSERT_EQUAL_UINT32(6, res.written);
	TEST_ASSERT_EQUAL_UINT64(100, slave_u(0x1017, 0)); /* entry 8 not written */
	TEST_ASSERT_EQUAL_UINT64(500, slave_u(FX_IDX_LIMITED, 0));
	/* 1020h:1 differs (no need to read :2) + 7 downloads; no 1020h
	 * write, no store */
	TEST_ASSERT_EQUAL_UINT(8, requests(ev0));
	TEST_ASSERT_EQUAL_UINT64(0, slave_u(0x1020, 1));
	TEST_ASSERT_EQUAL_UINT(0, tb_event_count(slv, CO_EV_STORE));
	TEST_ASSERT_EQUAL_STRING("failed", co_cfgmgr_state_to_string(co_cfgmgr_state_of(&job)));
}

static void test_verify_equal_skips_download(void)
{
	add_u(0x1017, 0, 100, 2);
	finish_cdcf();
	TEST_ASSERT_EQUAL_UINT32(0, tb_od_write(&bus, slv->node, 0x1020, 1, 14000));
	TEST_ASSERT_EQUAL_UINT32(0, tb_od_write(&bus, slv->node, 0x1020, 2, 3600000));
	size_t ev0 = mgr->n_ev;
	co_cfgmgr_params p = params();
	p.verify = true;
	p.date = 14000;
	p.time = 3600000;
	p.store = true;
	start(&p);
	TEST_ASSERT_EQUAL_INT(CO_CFGMGR_SKIPPED, res.outcome);
	TEST_ASSERT_EQUAL_UINT32(0, res.written);
	TEST_ASSERT_EQUAL_UINT(2, requests(ev0));           /* the two 1020h reads only */
	TEST_ASSERT_EQUAL_UINT64(1000, slave_u(0x1017, 0)); /* fixture default untouched */
	TEST_ASSERT_EQUAL_UINT(0, tb_event_count(slv, CO_EV_STORE));
}

static void test_verify_mismatch_downloads_records_and_stores(void)
{
	add_u(0x1017, 0, 100, 2);
	finish_cdcf();
	TEST_ASSERT_EQUAL_UINT32(0, tb_od_write(&bus, slv->node, 0x1020, 1, 14000));
	TEST_ASSERT_EQUAL_UINT32(0, tb_od_write(&bus, slv->node, 0x1020, 2, 1));
	size_t ev0 = mgr->n_ev;
	co_cfgmgr_params p = params();
	p.verify = true;
	p.date = 14000;
	p.time = 3600000;
	p.store = true;
	start(&p);
	TEST_ASSERT_EQUAL_INT(CO_CFGMGR_CONFIGURED, res.outcome);
	TEST_ASSERT_EQUAL_UINT32(1, res.written);
	/* reads 1020h:1, 1020h:2; the entry; writes 1020h:1, 1020h:2; 1010h:1 */
	TEST_ASSERT_EQUAL_UINT(6, requests(ev0));
	TEST_ASSERT_EQUAL_UINT64(100, slave_u(0x1017, 0));
	TEST_ASSERT_EQUAL_UINT64(14000, slave_u(0x1020, 1));
	TEST_ASSERT_EQUAL_UINT64(3600000, slave_u(0x1020, 2));
	TEST_ASSERT_EQUAL_UINT(1, tb_event_count(slv, CO_EV_STORE));
	TEST_ASSERT_EQUAL_UINT8(1, tb_last_event(slv, CO_EV_STORE)->u.store.sub);
	/* the store is the last request: after 1020h, so 1020h is saved too */
	TB_ASSERT_LAST(&bus, mgr->idx, 0x600 + SLAVE, "23 10 10 01 73 61 76 65");

	/* the next boot: 1020h matches now, nothing is downloaded */
	done_calls = 0;
	ev0 = mgr->n_ev;
	start(&p);
	TEST_ASSERT_EQUAL_INT(CO_CFGMGR_SKIPPED, res.outcome);
	TEST_ASSERT_EQUAL_UINT(2, requests(ev0));
}

static void test_slave_without_1020h_gets_full_download(void)
{
	/* a slave whose OD has no 1020h: the read aborts, the download runs,
	 * and recording 1020h afterwards fails with J on 1020h:1 */
	tb_fini(&bus);
	co_node_config scfg = { .node_id = SLAVE };
	co_node_config mcfg = { .node_id = 1, .sdo_client_count = 1 };
	co_od *mod;
	tb_init(&bus);
	slv = tb_add_node(&bus, &scfg, fx_od_new());
	TEST_ASSERT_EQUAL_INT(0, co_od_create(&mod, 16));
	mgr = tb_add_node(&bus, &mcfg, mod);
	tb_settle(&bus, 100000);
	tb_events_clear(mgr);
	add_u(0x1017, 0, 123, 2);
	finish_cdcf();
	co_cfgmgr_params p = params();
	p.verify = true;
	p.date = 5;
	p.time = 6;
	start(&p);
	TEST_ASSERT_EQUAL_UINT64(123, slave_u(0x1017, 0));
	TEST_ASSERT_EQUAL_UINT32(1, res.written);
	TEST_ASSERT_EQUAL_INT(CO_CFGMGR_FAILED_J, res.outcome);
	TEST_ASSERT_EQUAL_UINT32(0, res.entry); /* not a concise DCF entry */
	TEST_ASSERT_EQUAL_HEX16(0x1020, res.index);
	TEST_ASSERT_EQUAL_HEX8(1, res.sub);
	TEST_ASSERT_EQUAL_HEX32(0x06020000, res.abort);
}

static void test_restore_loads_resets_and_waits_for_bootup(void)
{
	add_u(0x1017, 0, 200, 2);
	finish_cdcf();
	TEST_ASSERT_EQUAL_UINT32(0, tb_od_write(&bus, slv->node, FX_IDX_LIMITED, 0, 777));
	size_t log0 = tb_log_count(&bus);
	co_cfgmgr_params p = params();
	p.restore_sub = 1;
	start(&p);
	TEST_ASSERT_EQUAL_INT(CO_CFGMGR_CONFIGURED, res.outcome);
	TEST_ASSERT_TRUE(res.restored);
	TEST_ASSERT_EQUAL_UINT(1, restores);
	/* "load" to 1011h:1, then NMT reset node (application) */
	bool load = false, reset = false, bootup = false;
	for (size_t i = log0; i < tb_log_count(&bus); i++) {
		const co_frame *f = tb_log_at(&bus, i);
		load |= tb_frame_is(f, 0x600 + SLAVE, "23 11 10 01 6C 6F 61 64");
		if (tb_frame_is(f, 0x000, "81 05")) {
			TEST_ASSERT_TRUE_MESSAGE(load, "reset before the load was confirmed");
			reset = true;
		}
		if (tb_frame_is(f, 0x700 + SLAVE, "00")) {
			TEST_ASSERT_TRUE(reset);
			bootup = true;
		}
		if (f->id == 0x600 + SLAVE && f->data[1] == 0x17 && f->data[2] == 0x10)
			TEST_ASSERT_TRUE_MESSAGE(bootup, "configured before the boot-up");
	}
	TEST_ASSERT_TRUE(bootup);
	/* the reset brought the fixture default back, then the config applied */
	TEST_ASSERT_EQUAL_UINT64(100, slave_u(FX_IDX_LIMITED, 0));
	TEST_ASSERT_EQUAL_UINT64(200, slave_u(0x1017, 0));
}

static void test_restore_comm_uses_reset_communication(void)
{
	finish_cdcf(); /* empty configuration */
	size_t log0 = tb_log_count(&bus);
	co_cfgmgr_params p = params();
	p.restore_sub = 2;
	start(&p);
	TEST_ASSERT_EQUAL_INT(CO_CFGMGR_CONFIGURED, res.outcome);
	TEST_ASSERT_EQUAL_UINT32(0, res.written);
	bool reset_comm = false;
	for (size_t i = log0; i < tb_log_count(&bus); i++)
		reset_comm |= tb_frame_is(tb_log_at(&bus, i), 0x000, "82 05");
	TEST_ASSERT_TRUE(reset_comm);
}

static tb_action drop_nmt(void *ctx, const co_frame *f, int from, uint64_t n)
{
	(void)ctx;
	(void)from;
	(void)n;
	return f->id == 0 ? TB_DROP : TB_DELIVER;
}

static void test_restore_without_bootup_fails(void)
{
	add_u(0x1017, 0, 200, 2);
	finish_cdcf();
	bus.filter = drop_nmt; /* the reset never reaches the slave */
	co_cfgmgr_params p = params();
	p.restore_sub = 3;
	p.bootup_wait_ms = 300;
	uint64_t t0 = bus.now;
	start(&p);
	TEST_ASSERT_EQUAL_INT(CO_CFGMGR_FAILED_J, res.outcome);
	TEST_ASSERT_EQUAL_HEX16(0x1011, res.index);
	TEST_ASSERT_EQUAL_HEX8(3, res.sub);
	TEST_ASSERT_EQUAL_HEX32(0x05040000, res.abort);
	TEST_ASSERT_EQUAL_UINT32(0, res.written);
	TEST_ASSERT_TRUE(bus.now - t0 >= 300000);
	TEST_ASSERT_TRUE(bus.now - t0 < 400000);
	TEST_ASSERT_EQUAL_UINT64(1000, slave_u(0x1017, 0));
}

static void test_refused_restore_load_fails(void)
{
	finish_cdcf();
	co_cfgmgr_params p = params();
	p.restore_sub = 9; /* the slave has subs 1..3 */
	start(&p);
	TEST_ASSERT_EQUAL_INT(CO_CFGMGR_FAILED_J, res.outcome);
	TEST_ASSERT_EQUAL_HEX16(0x1011, res.index);
	TEST_ASSERT_EQUAL_HEX8(9, res.sub);
	TEST_ASSERT_EQUAL_HEX32(0x06090011, res.abort);
}

static void test_start_checks_and_cancel(void)
{
	static const uint8_t broken[] = { 1, 0, 0, 0, 0x17, 0x10, 0 };
	co_cfgmgr_params p = params();
	p.cdcf = broken;
	p.cdcf_len = sizeof broken;
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_cfgmgr_start(&job, mgr->node, &p, bus.now));
	p = params();
	p.node_id = 0;
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_cfgmgr_start(&job, mgr->node, &p, bus.now));
	p = params();
	p.channel = 2; /* the manager has channels 0 and 1 */
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_cfgmgr_start(&job, mgr->node, &p, bus.now));
	TEST_ASSERT_EQUAL_INT(-ENOENT, co_cfgmgr_cancel(&job, bus.now));

	add_u(0x1017, 0, 100, 2);
	add_u(0x1017, 0, 200, 2);
	finish_cdcf();
	p = params();
	TEST_ASSERT_EQUAL_INT(0, co_cfgmgr_start(&job, mgr->node, &p, bus.now));
	TEST_ASSERT_TRUE(co_cfgmgr_running(&job));
	TEST_ASSERT_EQUAL_INT(-EBUSY, co_cfgmgr_start(&job, mgr->node, &p, bus.now));
	TEST_ASSERT_EQUAL_INT(0, co_cfgmgr_cancel(&job, bus.now));
	TEST_ASSERT_EQUAL_UINT(1, done_calls);
	TEST_ASSERT_EQUAL_INT(CO_CFGMGR_CANCELLED, res.outcome);
	TEST_ASSERT_FALSE(co_cfgmgr_running(&job));
	tb_settle(&bus, 1000000); /* the cancelled request's completion is ignored */
	TEST_ASSERT_EQUAL_UINT(1, done_calls);
	TEST_ASSERT_EQUAL_STRING("cancelled", co_cfgmgr_outcome_to_string(res.outcome));
}

static void test_pool_mode(void)
{
	add_u(0x1017, 0, 444, 2);
	add_u(FX_IDX_LIMITED, 0, 11, 2);
	finish_cdcf();
	co_cfgmgr_params p = params();
	p.channel = -1;
	start(&p);
	TEST_ASSERT_EQUAL_INT(CO_CFGMGR_CONFIGURED, res.outcome);
	TEST_ASSERT_EQUAL_UINT64(444, slave_u(0x1017, 0));
	TEST_ASSERT_EQUAL_UINT64(11, slave_u(FX_IDX_LIMITED, 0));
}

/* ---- the line: 1F22h/1F26h/1F27h/1F81h/1F8Ah in the manager's OD ---------------- */

static void line_drive(uint64_t limit_us)
{
	uint64_t end = bus.now + limit_us;

	while (!done_calls && bus.now < end) {
		tb_pump(&bus);
		for (; ev_seen < mgr->n_ev; ev_seen++)
			co_cfgmgr_line_on_event(&line, &mgr->ev[ev_seen], bus.now);
		co_cfgmgr_line_tick(&line, bus.now);
		tb_advance(&bus, 1000);
	}
	tb_settle(&bus, 10000);
}

static void line_setup(void)
{
	TEST_ASSERT_EQUAL_INT(0, co_od_add_cfgmgr_node(mgr->od, SLAVE, 4096));
	TEST_ASSERT_EQUAL_INT(0, co_od_add_cfgmgr_node(mgr->od, SLAVE, 4096)); /* kept */
	TEST_ASSERT_EQUAL_INT(0,
			      co_od_add_array(mgr->od, 0x1F81, CO_T_UNSIGNED32, 127, CO_ACC_RW, 0));
	co_cfgmgr_line_init(&line, mgr->node, on_done, NULL);
}

static uint32_t sdo_write(uint16_t index, uint8_t sub, const void *data, uint32_t len)
{
	co_od_access a = { .origin = CO_OD_ORIGIN_SDO, .data = data, .size = len };
	co_od_entry *e = co_od_find(mgr->od, index, sub);
	TEST_ASSERT_NOT_NULL(e);
	return co_od_write(e, data, len, &a);
}

static void test_line_configures_from_the_od(void)
{
	line_setup();
	TEST_ASSERT_EQUAL_INT(0,
			      co_cfgmgr_line_configure(&line, SLAVE, bus.now)); /* nothing to do */
	TEST_ASSERT_EQUAL_INT(0, co_cfgmgr_line_configure(&line, 9, bus.now));
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_cfgmgr_line_configure(&line, 0, bus.now));

	add_u(0x1017, 0, 321, 2);
	add_u(FX_IDX_LIMITED, 0, 12, 2);
	finish_cdcf();
	/* 1F22h:5 written as over SDO; a value that is no concise DCF is refused */
	TEST_ASSERT_EQUAL_HEX32(0x06090030, sdo_write(0x1F22, SLAVE, cdcf, (uint32_t)cdcf_len - 1));
	TEST_ASSERT_EQUAL_HEX32(0, sdo_write(0x1F22, SLAVE, cdcf, (uint32_t)cdcf_len));
	TEST_ASSERT_EQUAL_INT(0, co_od_set_u32(mgr->od, 0x1F26, SLAVE, 15000));
	TEST_ASSERT_EQUAL_INT(0, co_od_set_u32(mgr->od, 0x1F27, SLAVE, 1234));
	line.store[SLAVE] = true;

	TEST_ASSERT_EQUAL_INT(1, co_cfgmgr_line_configure(&line, SLAVE, bus.now));
	TEST_ASSERT_EQUAL_INT(-EBUSY, co_cfgmgr_line_configure(&line, SLAVE, bus.now));
	/* no new 1F22h:5 while node 5 is being configured */
	TEST_ASSERT_EQUAL_HEX32(0x08000022, sdo_write(0x1F22, SLAVE, cdcf, (uint32_t)cdcf_len));
	line_drive(10000000);
	TEST_ASSERT_EQUAL_UINT(1, done_calls);
	TEST_ASSERT_EQUAL_INT(CO_CFGMGR_CONFIGURED, res.outcome);
	TEST_ASSERT_EQUAL_UINT8(SLAVE, res.node_id);
	TEST_ASSERT_EQUAL_UINT64(321, slave_u(0x1017, 0));
	TEST_ASSERT_EQUAL_UINT64(12, slave_u(FX_IDX_LIMITED, 0));
	TEST_ASSERT_EQUAL_UINT64(15000, slave_u(0x1020, 1));
	TEST_ASSERT_EQUAL_UINT64(1234, slave_u(0x1020, 2));
	TEST_ASSERT_EQUAL_UINT(1, tb_event_count(slv, CO_EV_STORE));

	/* the next boot: 1020h matches */
	done_calls = 0;
	TEST_ASSERT_EQUAL_INT(1, co_cfgmgr_line_configure(&line, SLAVE, bus.now));
	line_drive(10000000);
	TEST_ASSERT_EQUAL_INT(CO_CFGMGR_SKIPPED, res.outcome);

	/* 1F81h:5 bit 7 with 1F8Ah:5 = 1: restore first (1020h is back to 0) */
	done_calls = 0;
	TEST_ASSERT_EQUAL_INT(0, co_od_set_u32(mgr->od, 0x1F81, SLAVE, 0x85));
	TEST_ASSERT_EQUAL_INT(0, co_od_set_u8(mgr->od, 0x1F8A, SLAVE, 1));
	TEST_ASSERT_EQUAL_INT(1, co_cfgmgr_line_configure(&line, SLAVE, bus.now));
	line_drive(10000000);
	TEST_ASSERT_EQUAL_INT(CO_CFGMGR_CONFIGURED, res.outcome);
	TEST_ASSERT_TRUE(res.restored);
	TEST_ASSERT_EQUAL_UINT(1, restores);
	TEST_ASSERT_EQUAL_UINT64(15000, slave_u(0x1020, 1));
}

static void test_line_refuses_a_broken_cdcf(void)
{
	static const uint8_t broken[] = { 2, 0, 0, 0, 0x17, 0x10, 0, 2, 0, 0, 0, 1, 0 };
	line_setup();
	/* a local write is not checked; the configure step is */
	TEST_ASSERT_EQUAL_INT(0, co_od_set_bytes(mgr->od, 0x1F22, SLAVE, broken, sizeof broken));
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_cfgmgr_line_configure(&line, SLAVE, bus.now));
	TEST_ASSERT_EQUAL_UINT(0, done_calls);
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_od_add_cfgmgr_node(mgr->od, 128, 16));
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_od_add_cfgmgr_node(mgr->od, 6, 0));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_twenty_entries_downloaded_in_order_and_read_back);
	RUN_TEST(test_first_abort_stops_with_j);
	RUN_TEST(test_verify_equal_skips_download);
	RUN_TEST(test_verify_mismatch_downloads_records_and_stores);
	RUN_TEST(test_slave_without_1020h_gets_full_download);
	RUN_TEST(test_restore_loads_resets_and_waits_for_bootup);
	RUN_TEST(test_restore_comm_uses_reset_communication);
	RUN_TEST(test_restore_without_bootup_fails);
	RUN_TEST(test_refused_restore_load_fails);
	RUN_TEST(test_start_checks_and_cancel);
	RUN_TEST(test_pool_mode);
	RUN_TEST(test_line_configures_from_the_od);
	RUN_TEST(test_line_refuses_a_broken_cdcf);
	return UNITY_END();
}
