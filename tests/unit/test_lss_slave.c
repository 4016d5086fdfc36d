/* SPDX-License-Identifier: MIT */
/*
 * LSS slave driven by scripted master frames (the transducer's golden
 * LSS frames, docs/cosim.md), then every master service against a real
 * slave wired in memory.
 */
#include <errno.h>
#include <string.h>

#include "core/co_internal.h" /* node->lss slot */
#include "core/lss_master.h"
#include "core/lss_slave.h"
#include "tests/unit/support/lss_fixture.h"
#include "unity.h"

#define MS 1000u

static tb_bus bus;
static lss_fixture slv;
static const lss_address sti = { { 0x250, 0, 0, 123456 } }; /* the transducer */

static void make_slave(uint8_t node_id, const lss_address *id, bool constant,
		       const lss_slave_hooks *hooks, void *ctx)
{
	co_node_config c = { .node_id = node_id,
			     .lss_slave = true,
			     .lss_slave_constant_id = constant,
			     .lss_slave_hooks = hooks,
			     .lss_slave_ctx = ctx };
	TEST_ASSERT_EQUAL_INT(0, lss_fixture_create(&slv, &bus, &c, id));
}

void setUp(void)
{
	lss_bus_init(&bus);
	make_slave(1, &sti, false, NULL, NULL);
}

void tearDown(void)
{
	tb_fini(&bus); /* the bus owns every node */
}

static void master_says(uint8_t b0, uint8_t b1, uint8_t b2, uint8_t b3, uint8_t b4)
{
	const uint8_t d[8] = { b0, b1, b2, b3, b4, 0, 0, 0 };

	lss_bus_inject(&bus, LSS_COBID_MASTER, d);
}

static unsigned n_answers(void)
{
	return tb_log_count_id(&bus, LSS_COBID_SLAVE);
}

/* The last answer must be these bytes. */
static void expect_answer(const uint8_t want[8])
{
	TEST_ASSERT_TRUE(n_answers() > 0);
	lss_fixture_expect_frame(&bus, n_answers() - 1, LSS_COBID_SLAVE, want);
}

static lss_state state(void)
{
	lss_state s;

	TEST_ASSERT_EQUAL_INT(0, lss_slave_get(slv.node, &s, NULL, NULL, NULL));
	return s;
}

static void expect_ids(uint8_t active, uint8_t pending, uint8_t persistent)
{
	uint8_t a, p, s;

	TEST_ASSERT_EQUAL_INT(0, lss_slave_get(slv.node, NULL, &a, &p, &s));
	TEST_ASSERT_EQUAL_UINT8_MESSAGE(active, a, "active");
	TEST_ASSERT_EQUAL_UINT8_MESSAGE(pending, p, "pending");
	TEST_ASSERT_EQUAL_UINT8_MESSAGE(persistent, s, "persistent");
	TEST_ASSERT_EQUAL_UINT8(active, co_node_id(slv.node));
}

/* ---- golden frames L1-L15 ------------------------------------------------------- */

static void test_golden_global_sequence(void)
{
	const uint8_t l3[8] = { 0x5E, 0x01, 0, 0, 0, 0, 0, 0 };
	const uint8_t l5[8] = { 0x11, 0x00, 0x00, 0, 0, 0, 0, 0 };
	const uint8_t l7[8] = { 0x13, 0x00, 0x00, 0, 0, 0, 0, 0 };
	const uint8_t l9[8] = { 0x17, 0x00, 0x00, 0, 0, 0, 0, 0 };

	TEST_ASSERT_EQUAL_INT(LSS_STATE_WAITING, state());
	master_says(0x04, 0x01, 0, 0, 0);       /* L1 */
	TEST_ASSERT_EQUAL_UINT(0, n_answers()); /* switch global is unanswered */
	TEST_ASSERT_EQUAL_INT(LSS_STATE_CONFIGURATION, state());
	int e = evlog_find(&slv.ev, 0, CO_EV_LSS_SLAVE_STATE);
	TEST_ASSERT_TRUE(e >= 0);
	TEST_ASSERT_EQUAL_UINT8(LSS_STATE_CONFIGURATION, slv.ev.ev[e].u.lss_slave.state);

	master_says(0x5E, 0, 0, 0, 0); /* L2 */
	expect_answer(l3);
	master_says(0x11, 0x05, 0, 0, 0); /* L4, NN = 5 */
	expect_answer(l5);
	expect_ids(1, 5, 1);
	master_says(0x13, 0x00, 0x04, 0, 0); /* L6: 125 kbit/s */
	expect_answer(l7);
	master_says(0x17, 0, 0, 0, 0); /* L8 */
	expect_answer(l9);
	expect_ids(1, 5, 5);
	e = evlog_find(&slv.ev, 0, CO_EV_LSS_SLAVE_STORE);
	TEST_ASSERT_TRUE(e >= 0);
	TEST_ASSERT_EQUAL_UINT8(5, slv.ev.ev[e].u.lss_slave.persistent_id);
	TEST_ASSERT_EQUAL_UINT8(1, slv.ev.ev[e].u.lss_slave.bt_valid);
	TEST_ASSERT_EQUAL_UINT8(4, slv.ev.ev[e].u.lss_slave.bt_index);
	master_says(0x04, 0x00, 0, 0, 0); /* L10 */
	TEST_ASSERT_EQUAL_INT(LSS_STATE_WAITING, state());
	/* A configured node does not reset by itself: active stays 1 until
	 * the NMT master resets communication. */
	expect_ids(1, 5, 5);
	co_node_reset_comm(slv.node, 5 * MS);
	expect_ids(5, 5, 5);
	TEST_ASSERT_EQUAL_UINT(4, n_answers());
}

static void test_golden_switch_selective(void)
{
	const uint8_t l15[8] = { 0x44, 0, 0, 0, 0, 0, 0, 0 };

	master_says(0x40, 0x50, 0x02, 0x00, 0x00); /* L11 */
	master_says(0x41, 0, 0, 0, 0);             /* L12 */
	master_says(0x42, 0, 0, 0, 0);             /* L13 */
	TEST_ASSERT_EQUAL_UINT(0, n_answers());
	TEST_ASSERT_EQUAL_INT(LSS_STATE_WAITING, state());
	master_says(0x43, 0x40, 0xE2, 0x01, 0x00); /* L14 */
	TEST_ASSERT_EQUAL_UINT(1, n_answers());
	expect_answer(l15);
	TEST_ASSERT_EQUAL_INT(LSS_STATE_CONFIGURATION, state());
}

static void test_switch_selective_mismatch_and_order(void)
{
	master_says(0x40, 0x50, 0x02, 0, 0);
	master_says(0x41, 0, 0, 0, 0);
	master_says(0x42, 0, 0, 0, 0);
	master_says(0x43, 0xF1, 0xFB, 0x09, 0); /* serial 654321: other device */
	TEST_ASSERT_EQUAL_UINT(0, n_answers());
	/* Out of order: serial before revision. */
	master_says(0x40, 0x50, 0x02, 0, 0);
	master_says(0x41, 0, 0, 0, 0);
	master_says(0x43, 0x40, 0xE2, 0x01, 0);
	master_says(0x42, 0, 0, 0, 0);
	TEST_ASSERT_EQUAL_UINT(0, n_answers());
	/* Without the vendor frame first. */
	master_says(0x41, 0, 0, 0, 0);
	master_says(0x42, 0, 0, 0, 0);
	master_says(0x43, 0x40, 0xE2, 0x01, 0);
	TEST_ASSERT_EQUAL_UINT(0, n_answers());
	TEST_ASSERT_EQUAL_INT(LSS_STATE_WAITING, state());
	/* A fresh full sequence still works. */
	master_says(0x40, 0x50, 0x02, 0, 0);
	master_says(0x41, 0, 0, 0, 0);
	master_says(0x42, 0, 0, 0, 0);
	master_says(0x43, 0x40, 0xE2, 0x01, 0);
	TEST_ASSERT_EQUAL_UINT(1, n_answers());
}

/* ---- states ------------------------------------------------------------------------ */

static void test_waiting_state_ignores_configuration_services(void)
{
	master_says(0x11, 0x05, 0, 0, 0);
	master_says(0x13, 0x00, 0x02, 0, 0);
	master_says(0x15, 0x10, 0x00, 0, 0);
	master_says(0x17, 0, 0, 0, 0);
	for (uint8_t cs = 0x5A; cs <= 0x5E; cs++)
		master_says(cs, 0, 0, 0, 0);
	master_says(0x04, 0x02, 0, 0, 0); /* reserved mode */
	master_says(0x99, 0, 0, 0, 0);    /* unknown cs */
	TEST_ASSERT_EQUAL_UINT(0, n_answers());
	expect_ids(1, 1, 1);
	TEST_ASSERT_EQUAL_INT(LSS_STATE_WAITING, state());
	TEST_ASSERT_EQUAL_UINT(0, evlog_count(&slv.ev, CO_EV_LSS_SLAVE_STATE));
}

static void test_inquire_identity_from_1018(void)
{
	const lss_address id = { { 0x11223344, 0x55667788, 0x00020001, 0xCAFEBABE } };

	tb_fini(&bus);
	lss_bus_init(&bus);
	make_slave(9, &id, false, NULL, NULL);
	master_says(0x04, 0x01, 0, 0, 0);
	for (unsigned i = 0; i < 4; i++) {
		uint32_t v = id.id[i];
		const uint8_t want[8] = { (uint8_t)(0x5A + i),
					  (uint8_t)v,
					  (uint8_t)(v >> 8),
					  (uint8_t)(v >> 16),
					  (uint8_t)(v >> 24),
					  0,
					  0,
					  0 };
		master_says((uint8_t)(0x5A + i), 0, 0, 0, 0);
		expect_answer(want);
	}
	/* Identity is read live from the OD. */
	TEST_ASSERT_EQUAL_INT(0, co_od_set_u32(slv.od, 0x1018, 4, 7));
	master_says(0x5D, 0, 0, 0, 0);
	const uint8_t seven[8] = { 0x5D, 7, 0, 0, 0, 0, 0, 0 };
	expect_answer(seven);
}

/* ---- node-IDs ------------------------------------------------------------------------ */

static void test_config_node_id_range(void)
{
	const uint8_t ok[8] = { 0x11, 0, 0, 0, 0, 0, 0, 0 };
	const uint8_t bad[8] = { 0x11, 0x01, 0, 0, 0, 0, 0, 0 };

	master_says(0x04, 0x01, 0, 0, 0);
	master_says(0x11, 0, 0, 0, 0);
	expect_answer(bad);
	master_says(0x11, 128, 0, 0, 0);
	expect_answer(bad);
	master_says(0x11, 200, 0, 0, 0);
	expect_answer(bad);
	expect_ids(1, 1, 1);
	TEST_ASSERT_EQUAL_UINT(0, evlog_count(&slv.ev, CO_EV_LSS_SLAVE_NODE_ID));
	master_says(0x11, 127, 0, 0, 0);
	expect_answer(ok);
	expect_ids(1, 127, 1);
	master_says(0x11, 255, 0, 0, 0); /* 255: become unconfigured */
	expect_answer(ok);
	expect_ids(1, 255, 1);
	TEST_ASSERT_EQUAL_UINT(2, evlog_count(&slv.ev, CO_EV_LSS_SLAVE_NODE_ID));
}

static void test_unconfigured_slave_resets_itself_on_waiting(void)
{
	tb_fini(&bus);
	lss_bus_init(&bus);
	make_slave(LSS_NODE_ID_UNCONFIGURED, &sti, false, NULL, NULL);
	expect_ids(255, 255, 255);
	master_says(0x04, 0x01, 0, 0, 0);
	master_says(0x11, 7, 0, 0, 0);
	expect_ids(255, 7, 255);
	unsigned before = slv.ev.n;
	master_says(0x04, 0x00, 0, 0, 0);
	TEST_ASSERT_EQUAL_INT(LSS_STATE_WAITING, state());
	expect_ids(7, 7, 255); /* automatic reset communication */
	/* Order: the state change first, then the node-ID change. */
	int st = evlog_find(&slv.ev, before, CO_EV_LSS_SLAVE_STATE);
	int id = evlog_find(&slv.ev, before, CO_EV_LSS_SLAVE_NODE_ID);
	TEST_ASSERT_TRUE(st >= 0 && id > st);
	TEST_ASSERT_EQUAL_UINT8(7, slv.ev.ev[id].u.lss_slave.active_id);
	/* Not again on the next switch. */
	master_says(0x04, 0x01, 0, 0, 0);
	master_says(0x04, 0x00, 0, 0, 0);
	TEST_ASSERT_EQUAL_UINT(2, evlog_count(&slv.ev, CO_EV_LSS_SLAVE_NODE_ID));
}

static void test_constant_id_refuses_store(void)
{
	const uint8_t unsupported[8] = { 0x17, 0x01, 0, 0, 0, 0, 0, 0 };

	tb_fini(&bus);
	lss_bus_init(&bus);
	make_slave(3, &sti, true, NULL, NULL);
	master_says(0x04, 0x01, 0, 0, 0);
	master_says(0x17, 0, 0, 0, 0);
	expect_answer(unsupported);
	TEST_ASSERT_EQUAL_UINT(0, evlog_count(&slv.ev, CO_EV_LSS_SLAVE_STORE));
}

/* Hooks: a storage that fails, a device with only 250/500 kbit/s. */
typedef struct hook_state {
	uint8_t store_ec, store_spec;
	unsigned stores;
	uint8_t stored_id;
} hook_state;

static uint8_t hook_bt(void *ctx, uint8_t table, uint8_t index, uint8_t *spec)
{
	(void)ctx;
	if (table != 0) {
		*spec = 0x42;
		return LSS_EC_SPECIFIC;
	}
	return (index == 2 || index == 3) ? LSS_EC_OK : LSS_EC_BIT_TIMING_UNSUPP;
}

static uint8_t hook_store(void *ctx, uint8_t node_id, bool bt_valid, uint8_t table, uint8_t index,
			  uint8_t *spec)
{
	hook_state *h = ctx;

	(void)bt_valid;
	(void)table;
	(void)index;
	h->stores++;
	h->stored_id = node_id;
	*spec = h->store_spec;
	return h->store_ec;
}

static void test_hooks_decide_store_and_bit_timing(void)
{
	static const lss_slave_hooks hooks = { .check_bit_timing = hook_bt, .store = hook_store };
	hook_state h = { .store_ec = LSS_EC_STORE_ACCESS };
	const uint8_t media[8] = { 0x17, 0x02, 0, 0, 0, 0, 0, 0 };
	const uint8_t specific[8] = { 0x17, 0xFF, 0x09, 0, 0, 0, 0, 0 };
	const uint8_t ok[8] = { 0x17, 0, 0, 0, 0, 0, 0, 0 };
	const uint8_t bt_ok[8] = { 0x13, 0, 0, 0, 0, 0, 0, 0 };
	const uint8_t bt_no[8] = { 0x13, 0x01, 0, 0, 0, 0, 0, 0 };
	const uint8_t bt_spec[8] = { 0x13, 0xFF, 0x42, 0, 0, 0, 0, 0 };

	tb_fini(&bus);
	lss_bus_init(&bus);
	make_slave(4, &sti, false, &hooks, &h);
	master_says(0x04, 0x01, 0, 0, 0);
	master_says(0x11, 6, 0, 0, 0);
	master_says(0x17, 0, 0, 0, 0);
	expect_answer(media);
	expect_ids(4, 6, 4); /* persistent unchanged on failure */
	h.store_ec = LSS_EC_SPECIFIC;
	h.store_spec = 9;
	master_says(0x17, 0, 0, 0, 0);
	expect_answer(specific);
	h.store_ec = LSS_EC_OK;
	master_says(0x17, 0, 0, 0, 0);
	expect_answer(ok);
	expect_ids(4, 6, 6);
	TEST_ASSERT_EQUAL_UINT(3, h.stores);
	TEST_ASSERT_EQUAL_UINT8(6, h.stored_id);

	master_says(0x13, 0, 4, 0, 0);
	expect_answer(bt_no);
	master_says(0x13, 0, 3, 0, 0);
	expect_answer(bt_ok);
	master_says(0x13, 1, 0, 0, 0);
	expect_answer(bt_spec);
}

static void test_default_bit_timing_table_and_activate(void)
{
	const uint8_t ok[8] = { 0x13, 0, 0, 0, 0, 0, 0, 0 };
	const uint8_t no[8] = { 0x13, 0x01, 0, 0, 0, 0, 0, 0 };

	master_says(0x04, 0x01, 0, 0, 0);
	/* Activate without a configured bit timing does nothing. */
	master_says(0x15, 0x64, 0x00, 0, 0);
	TEST_ASSERT_EQUAL_UINT(0, evlog_count(&slv.ev, CO_EV_LSS_SLAVE_BIT_TIMING));
	for (uint8_t i = 0; i <= 9; i++) {
		master_says(0x13, 0, i, 0, 0);
		expect_answer(i == 5 || i == 9 ? no : ok);
	}
	master_says(0x13, 1, 0, 0, 0); /* other tables: unsupported */
	expect_answer(no);
	master_says(0x13, 0, 2, 0, 0);       /* 500 kbit/s */
	master_says(0x15, 0xF4, 0x01, 0, 0); /* 500 ms */
	int e = evlog_find(&slv.ev, 0, CO_EV_LSS_SLAVE_BIT_TIMING);
	TEST_ASSERT_TRUE(e >= 0);
	TEST_ASSERT_EQUAL_UINT16(500, slv.ev.ev[e].u.lss_slave.delay_ms);
	TEST_ASSERT_EQUAL_UINT8(0, slv.ev.ev[e].u.lss_slave.bt_table);
	TEST_ASSERT_EQUAL_UINT8(2, slv.ev.ev[e].u.lss_slave.bt_index);
}

/* ---- identification ------------------------------------------------------------------- */

static void identify(uint32_t v, uint32_t p, uint32_t rlo, uint32_t rhi, uint32_t slo, uint32_t shi)
{
	const uint32_t x[6] = { v, p, rlo, rhi, slo, shi };

	for (unsigned i = 0; i < 6; i++)
		master_says((uint8_t)(0x46 + i), (uint8_t)x[i], (uint8_t)(x[i] >> 8),
			    (uint8_t)(x[i] >> 16), (uint8_t)(x[i] >> 24));
}

static void test_identify_remote_ranges(void)
{
	const uint8_t hit[8] = { 0x4F, 0, 0, 0, 0, 0, 0, 0 };

	identify(0x250, 0, 0, 0, 123456, 123456); /* bounds included */
	TEST_ASSERT_EQUAL_UINT(1, n_answers());
	expect_answer(hit);
	identify(0x250, 0, 0, 5, 100000, 200000);
	TEST_ASSERT_EQUAL_UINT(2, n_answers());
	identify(0x250, 0, 0, 5, 123457, 200000); /* serial below range */
	identify(0x250, 0, 1, 5, 0, 200000);      /* revision below range */
	identify(0x251, 0, 0, 5, 0, 200000);      /* vendor */
	identify(0x250, 1, 0, 5, 0, 200000);      /* product */
	identify(0x250, 0, 0, 5, 0, 123455);      /* serial above range */
	TEST_ASSERT_EQUAL_UINT(2, n_answers());
	/* Also in configuration state. */
	master_says(0x04, 0x01, 0, 0, 0);
	identify(0x250, 0, 0, 0xFFFFFFFF, 0, 0xFFFFFFFF);
	TEST_ASSERT_EQUAL_UINT(3, n_answers());
	/* A missing frame in the sequence: no answer. */
	master_says(0x46, 0x50, 0x02, 0, 0);
	master_says(0x47, 0, 0, 0, 0);
	master_says(0x49, 0xFF, 0xFF, 0xFF, 0xFF);
	master_says(0x4A, 0, 0, 0, 0);
	master_says(0x4B, 0xFF, 0xFF, 0xFF, 0xFF);
	TEST_ASSERT_EQUAL_UINT(3, n_answers());
}

static void test_identify_non_configured(void)
{
	const uint8_t hit[8] = { 0x50, 0, 0, 0, 0, 0, 0, 0 };

	master_says(0x4C, 0, 0, 0, 0); /* configured (id 1): silent */
	TEST_ASSERT_EQUAL_UINT(0, n_answers());
	tb_fini(&bus);
	lss_bus_init(&bus);
	make_slave(LSS_NODE_ID_UNCONFIGURED, &sti, false, NULL, NULL);
	master_says(0x4C, 0, 0, 0, 0);
	expect_answer(hit);
	master_says(0x04, 0x01, 0, 0, 0);
	master_says(0x4C, 0, 0, 0, 0); /* both states */
	TEST_ASSERT_EQUAL_UINT(2, n_answers());
	master_says(0x11, 9, 0, 0, 0); /* pending valid: no longer "non-configured" */
	master_says(0x4C, 0, 0, 0, 0);
	TEST_ASSERT_EQUAL_UINT(3, n_answers()); /* only the 11h answer */
	TEST_ASSERT_EQUAL_HEX8(0x11,
			       tb_log_at(&bus, (size_t)tb_log_nth_id(&bus, 0x7E4, 2))->data[0]);
}

static void test_short_and_rtr_frames(void)
{
	co_frame f;

	/* A master that trims reserved bytes: read as zero padded. */
	co_frame_init(&f, LSS_COBID_MASTER, 2);
	f.data[0] = 0x04;
	f.data[1] = 0x01;
	co_node_recv(slv.node, &f, 0);
	TEST_ASSERT_EQUAL_INT(LSS_STATE_CONFIGURATION, state());
	co_frame_init(&f, LSS_COBID_MASTER, 0);
	co_node_recv(slv.node, &f, 0);
	co_frame_init(&f, LSS_COBID_MASTER, 8);
	f.flags = CO_FRAME_RTR;
	f.data[0] = 0x5E;
	co_node_recv(slv.node, &f, 0);
	tb_pump(&bus);
	TEST_ASSERT_EQUAL_UINT(0, n_answers());
}

/* ---- master and slave wired in memory ----------------------------------------------------- */

static lss_fixture mst;

static void make_master(void)
{
	co_node_config c = { .node_id = 0x7F, .lss_master = true };
	TEST_ASSERT_EQUAL_INT(0, lss_fixture_create(&mst, &bus, &c, NULL));
}

static const co_ev_lss_master *done(unsigned nth)
{
	unsigned k = 0;

	for (unsigned i = 0; i < mst.ev.n; i++)
		if (mst.ev.ev[i].kind == CO_EV_LSS_MASTER_DONE && k++ == nth)
			return &mst.ev.ev[i].u.lss_master;
	TEST_FAIL_MESSAGE("missing CO_EV_LSS_MASTER_DONE");
	return NULL;
}

static void test_master_and_slave_in_memory(void)
{
	const lss_address lo = { { 0x250, 0, 0, 100000 } };
	const lss_address hi = { { 0, 0, 10, 200000 } };
	uint64_t t = 0;

	make_master();
	/* Queue the whole commissioning at once: the master runs it in order. */
	TEST_ASSERT_EQUAL_INT(0, lss_master_identify_remote_req(mst.node, &lo, &hi, 1, t));
	TEST_ASSERT_EQUAL_INT(0, lss_master_switch_selective_req(mst.node, &sti, 2, t));
	TEST_ASSERT_EQUAL_INT(0, lss_master_inquire_req(mst.node, LSS_SVC_INQUIRE_VENDOR, 3, t));
	TEST_ASSERT_EQUAL_INT(0, lss_master_inquire_req(mst.node, LSS_SVC_INQUIRE_SERIAL, 4, t));
	TEST_ASSERT_EQUAL_INT(0, lss_master_inquire_req(mst.node, LSS_SVC_INQUIRE_NODE_ID, 5, t));
	TEST_ASSERT_EQUAL_INT(0, lss_master_config_node_id_req(mst.node, 0, 6, t));
	TEST_ASSERT_EQUAL_INT(0, lss_master_config_node_id_req(mst.node, 12, 7, t));
	TEST_ASSERT_EQUAL_INT(0, lss_master_config_bit_timing_req(mst.node, 0, 5, 8, t));
	tb_advance_to(&bus, 5000 * MS);
	TEST_ASSERT_EQUAL_INT(0, lss_master_config_bit_timing_req(mst.node, 0, 3, 9, bus.now));
	TEST_ASSERT_EQUAL_INT(0, lss_master_store_req(mst.node, 10, bus.now));
	TEST_ASSERT_EQUAL_INT(0, lss_master_activate_bit_timing_req(mst.node, 100, 11, bus.now));
	TEST_ASSERT_EQUAL_INT(
		0, lss_master_switch_global_req(mst.node, LSS_STATE_WAITING, 12, bus.now));
	TEST_ASSERT_EQUAL_INT(0, lss_master_identify_non_configured_req(mst.node, 13, bus.now));
	tb_advance(&bus, 5000 * MS);

	TEST_ASSERT_EQUAL_UINT(13, evlog_count(&mst.ev, CO_EV_LSS_MASTER_DONE));
	for (unsigned i = 0; i < 13; i++)
		TEST_ASSERT_EQUAL_UINT64(i + 1, done(i)->tag);
	TEST_ASSERT_EQUAL_UINT8(LSS_RESULT_OK, done(0)->result);
	TEST_ASSERT_EQUAL_UINT16(1, done(0)->answers);
	TEST_ASSERT_EQUAL_UINT8(LSS_RESULT_OK, done(1)->result);
	TEST_ASSERT_EQUAL_HEX32(0x250, done(2)->value);
	TEST_ASSERT_EQUAL_UINT32(123456, done(3)->value);
	TEST_ASSERT_EQUAL_UINT8(1, done(4)->node_id);
	TEST_ASSERT_EQUAL_UINT8(LSS_RESULT_SLAVE_ERROR, done(5)->result);
	TEST_ASSERT_EQUAL_UINT8(LSS_EC_NODE_ID_RANGE, done(5)->error_code);
	TEST_ASSERT_EQUAL_UINT8(LSS_RESULT_OK, done(6)->result);
	TEST_ASSERT_EQUAL_UINT8(LSS_RESULT_SLAVE_ERROR, done(7)->result); /* index 5 reserved */
	TEST_ASSERT_EQUAL_UINT8(LSS_EC_BIT_TIMING_UNSUPP, done(7)->error_code);
	TEST_ASSERT_EQUAL_UINT8(LSS_RESULT_OK, done(8)->result);
	TEST_ASSERT_EQUAL_UINT8(LSS_RESULT_OK, done(9)->result);
	TEST_ASSERT_EQUAL_UINT8(LSS_RESULT_OK, done(10)->result);
	TEST_ASSERT_EQUAL_UINT8(LSS_RESULT_OK, done(11)->result);
	TEST_ASSERT_EQUAL_UINT8(LSS_RESULT_NOT_FOUND, done(12)->result); /* it has an id */

	expect_ids(1, 12, 12);
	TEST_ASSERT_EQUAL_INT(LSS_STATE_WAITING, state());
	int e = evlog_find(&slv.ev, 0, CO_EV_LSS_SLAVE_BIT_TIMING);
	TEST_ASSERT_TRUE(e >= 0);
	TEST_ASSERT_EQUAL_UINT8(3, slv.ev.ev[e].u.lss_slave.bt_index);
	TEST_ASSERT_EQUAL_UINT16(100, slv.ev.ev[e].u.lss_slave.delay_ms);
}

static void test_master_times_out_against_silent_slave(void)
{
	make_master();
	/* The slave is in waiting state: inquire goes unanswered. */
	TEST_ASSERT_EQUAL_INT(0, lss_master_inquire_req(mst.node, LSS_SVC_INQUIRE_NODE_ID, 1, 0));
	tb_advance_to(&bus, 999 * MS);
	TEST_ASSERT_EQUAL_UINT(0, evlog_count(&mst.ev, CO_EV_LSS_MASTER_DONE));
	tb_advance_to(&bus, 1000 * MS);
	TEST_ASSERT_EQUAL_UINT8(LSS_RESULT_TIMEOUT, done(0)->result);
	TEST_ASSERT_EQUAL_UINT(0, n_answers());
}

static void test_node_without_slave(void)
{
	lss_fixture n;
	co_node_config c = { .node_id = 3 };

	TEST_ASSERT_EQUAL_INT(0, lss_fixture_create(&n, &bus, &c, &sti));
	TEST_ASSERT_EQUAL_INT(-ENODEV, lss_slave_get(n.node, NULL, NULL, NULL, NULL));
	TEST_ASSERT_NULL(n.node->lss);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_golden_global_sequence);
	RUN_TEST(test_golden_switch_selective);
	RUN_TEST(test_switch_selective_mismatch_and_order);
	RUN_TEST(test_waiting_state_ignores_configuration_services);
	RUN_TEST(test_inquire_identity_from_1018);
	RUN_TEST(test_config_node_id_range);
	RUN_TEST(test_unconfigured_slave_resets_itself_on_waiting);
	RUN_TEST(test_constant_id_refuses_store);
	RUN_TEST(test_hooks_decide_store_and_bit_timing);
	RUN_TEST(test_default_bit_timing_table_and_activate);
	RUN_TEST(test_identify_remote_ranges);
	RUN_TEST(test_identify_non_configured);
	RUN_TEST(test_short_and_rtr_frames);
	RUN_TEST(test_master_and_slave_in_memory);
	RUN_TEST(test_master_times_out_against_silent_slave);
	RUN_TEST(test_node_without_slave);
	return UNITY_END();
}
