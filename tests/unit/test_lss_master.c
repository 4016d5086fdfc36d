/* SPDX-License-Identifier: MIT */
/*
 * LSS master against a scripted slave: every frame the master sends is
 * checked byte by byte, answers are injected by the test, the clock is
 * stepped explicitly. Golden frames: the transducer's LSS
 * frames L1-L15 (docs/cosim.md), CiA 305 §8.
 */
#include <errno.h>
#include <string.h>

#include "core/lss_master.h"
#include "tests/unit/support/lss_fixture.h"
#include "unity.h"

#define MS 1000u

static tb_bus bus;
static lss_fixture mst;

static co_node_config master_cfg(void)
{
	co_node_config c = { .node_id = 0x7F, .lss_master = true };
	return c;
}

void setUp(void)
{
	co_node_config c = master_cfg();

	lss_bus_init(&bus);
	TEST_ASSERT_EQUAL_INT(0, lss_fixture_create(&mst, &bus, &c, NULL));
}

void tearDown(void)
{
	tb_fini(&bus); /* the bus owns every node */
}

/* Answer as the scripted slave and deliver. */
static void slave_says(uint8_t b0, uint8_t b1, uint8_t b2, uint8_t b3, uint8_t b4)
{
	const uint8_t d[8] = { b0, b1, b2, b3, b4, 0, 0, 0 };

	lss_bus_inject(&bus, LSS_COBID_SLAVE, d);
}

/* The last LSS_MASTER_DONE event; fails if none. */
static const co_ev_lss_master *last_done(void)
{
	for (unsigned i = mst.ev.n; i-- > 0;)
		if (mst.ev.ev[i].kind == CO_EV_LSS_MASTER_DONE)
			return &mst.ev.ev[i].u.lss_master;
	TEST_FAIL_MESSAGE("no CO_EV_LSS_MASTER_DONE");
	return NULL;
}

/* Frames the master sent (other services' frames do not count). */
static unsigned n_tx(void)
{
	return tb_log_count_id(&bus, LSS_COBID_MASTER);
}

/* The n-th frame the master sent, and the time it went out. */
static const co_frame *tx(unsigned n)
{
	int i = tb_log_nth_id(&bus, LSS_COBID_MASTER, n);

	TEST_ASSERT_TRUE(i >= 0);
	return tb_log_at(&bus, (size_t)i);
}

static uint64_t tx_time(unsigned n)
{
	int i = tb_log_nth_id(&bus, LSS_COBID_MASTER, n);

	TEST_ASSERT_TRUE(i >= 0);
	return tb_log_time(&bus, (size_t)i);
}

/* The master's real next deadline (ticking settles the node's cached one,
 * which may be early). */
static uint64_t deadline(void)
{
	return co_node_tick(mst.node, bus.now);
}

static unsigned n_done(void)
{
	return evlog_count(&mst.ev, CO_EV_LSS_MASTER_DONE);
}

static void expect_done(lss_master_service svc, lss_result r, uint64_t tag)
{
	const co_ev_lss_master *d = last_done();

	TEST_ASSERT_EQUAL_STRING(lss_master_service_to_string(svc),
				 lss_master_service_to_string(d->service));
	TEST_ASSERT_EQUAL_STRING(lss_result_to_string(r), lss_result_to_string(d->result));
	TEST_ASSERT_EQUAL_UINT64(tag, d->tag);
}

/* ---- golden frames ---------------------------------------------------------- */

static void test_golden_switch_selective_serial_123456(void)
{
	const lss_address a = { { 0x250, 0, 0, 123456 } };
	const uint8_t l11[8] = { 0x40, 0x50, 0x02, 0, 0, 0, 0, 0 };
	const uint8_t l12[8] = { 0x41, 0, 0, 0, 0, 0, 0, 0 };
	const uint8_t l13[8] = { 0x42, 0, 0, 0, 0, 0, 0, 0 };
	const uint8_t l14[8] = { 0x43, 0x40, 0xE2, 0x01, 0, 0, 0, 0 };

	TEST_ASSERT_EQUAL_INT(0, lss_master_switch_selective_req(mst.node, &a, 42, 0));
	tb_pump(&bus);
	TEST_ASSERT_EQUAL_UINT(4, n_tx());
	lss_fixture_expect_frame(&bus, 0, 0x7E5, l11);
	lss_fixture_expect_frame(&bus, 1, 0x7E5, l12);
	lss_fixture_expect_frame(&bus, 2, 0x7E5, l13);
	lss_fixture_expect_frame(&bus, 3, 0x7E5, l14);
	TEST_ASSERT_EQUAL_UINT(0, n_done());
	TEST_ASSERT_EQUAL_UINT(1, lss_master_pending(mst.node));
	tb_advance_to(&bus, 10 * MS);
	slave_says(0x44, 0, 0, 0, 0); /* L15 */
	TEST_ASSERT_EQUAL_UINT(1, n_done());
	expect_done(LSS_SVC_SWITCH_SELECTIVE, LSS_RESULT_OK, 42);
	TEST_ASSERT_EQUAL_UINT64(10 * MS, mst.ev.ev[mst.ev.n - 1].now_us);
	TEST_ASSERT_EQUAL_UINT(0, lss_master_pending(mst.node));
	TEST_ASSERT_EQUAL_UINT64(CO_NO_DEADLINE, deadline());
}

static void test_golden_configure_sequence(void)
{
	const uint8_t l1[8] = { 0x04, 0x01, 0, 0, 0, 0, 0, 0 };
	const uint8_t l2[8] = { 0x5E, 0, 0, 0, 0, 0, 0, 0 };
	const uint8_t l4[8] = { 0x11, 0x05, 0, 0, 0, 0, 0, 0 };
	const uint8_t l6[8] = { 0x13, 0x00, 0x04, 0, 0, 0, 0, 0 };
	const uint8_t l8[8] = { 0x17, 0, 0, 0, 0, 0, 0, 0 };
	const uint8_t l10[8] = { 0x04, 0x00, 0, 0, 0, 0, 0, 0 };

	/* L1: unconfirmed, done as soon as it is out. */
	TEST_ASSERT_EQUAL_INT(
		0, lss_master_switch_global_req(mst.node, LSS_STATE_CONFIGURATION, 1, 0));
	lss_fixture_expect_frame(&bus, 0, 0x7E5, l1);
	tb_advance_to(&bus, bus.now); /* confirmed by the next tick, never inside the request */
	expect_done(LSS_SVC_SWITCH_GLOBAL, LSS_RESULT_OK, 1);

	/* L2/L3 */
	TEST_ASSERT_EQUAL_INT(0, lss_master_inquire_req(mst.node, LSS_SVC_INQUIRE_NODE_ID, 2, 0));
	lss_fixture_expect_frame(&bus, 1, 0x7E5, l2);
	slave_says(0x5E, 0x01, 0, 0, 0);
	expect_done(LSS_SVC_INQUIRE_NODE_ID, LSS_RESULT_OK, 2);
	TEST_ASSERT_EQUAL_UINT8(1, last_done()->node_id);

	/* L4/L5 */
	TEST_ASSERT_EQUAL_INT(0, lss_master_config_node_id_req(mst.node, 5, 3, 0));
	lss_fixture_expect_frame(&bus, 2, 0x7E5, l4);
	slave_says(0x11, 0x00, 0x00, 0, 0);
	expect_done(LSS_SVC_CONFIG_NODE_ID, LSS_RESULT_OK, 3);
	TEST_ASSERT_EQUAL_UINT8(5, last_done()->node_id);
	TEST_ASSERT_EQUAL_UINT8(0, last_done()->error_code);

	/* L6/L7 */
	TEST_ASSERT_EQUAL_INT(0, lss_master_config_bit_timing_req(mst.node, 0, 4, 4, 0));
	lss_fixture_expect_frame(&bus, 3, 0x7E5, l6);
	slave_says(0x13, 0x00, 0x00, 0, 0);
	expect_done(LSS_SVC_CONFIG_BIT_TIMING, LSS_RESULT_OK, 4);

	/* L8/L9 */
	TEST_ASSERT_EQUAL_INT(0, lss_master_store_req(mst.node, 5, 0));
	lss_fixture_expect_frame(&bus, 4, 0x7E5, l8);
	slave_says(0x17, 0x00, 0x00, 0, 0);
	expect_done(LSS_SVC_STORE, LSS_RESULT_OK, 5);

	/* L10 */
	TEST_ASSERT_EQUAL_INT(0, lss_master_switch_global_req(mst.node, LSS_STATE_WAITING, 6, 0));
	lss_fixture_expect_frame(&bus, 5, 0x7E5, l10);
	tb_advance_to(&bus, bus.now); /* confirmed by the next tick, never inside the request */
	expect_done(LSS_SVC_SWITCH_GLOBAL, LSS_RESULT_OK, 6);
	TEST_ASSERT_EQUAL_UINT(6, n_done());
	TEST_ASSERT_EQUAL_UINT(6, n_tx());
}

/* ---- error answers ---------------------------------------------------------------- */

static void test_config_node_id_slave_errors(void)
{
	const uint8_t out_of_range[8] = { 0x11, 0x80, 0, 0, 0, 0, 0, 0 };

	TEST_ASSERT_EQUAL_INT(0, lss_master_config_node_id_req(mst.node, 0x80, 7, 0));
	lss_fixture_expect_frame(&bus, 0, 0x7E5, out_of_range); /* sent as given */
	slave_says(0x11, 0x01, 0x00, 0, 0);
	expect_done(LSS_SVC_CONFIG_NODE_ID, LSS_RESULT_SLAVE_ERROR, 7);
	TEST_ASSERT_EQUAL_UINT8(1, last_done()->error_code);
	TEST_ASSERT_EQUAL_STRING("node-ID out of range",
				 lss_error_to_string(LSS_CS_CONFIG_NODE_ID, 1));

	TEST_ASSERT_EQUAL_INT(0, lss_master_config_node_id_req(mst.node, 9, 8, 0));
	slave_says(0x11, 0xFF, 0x33, 0, 0);
	expect_done(LSS_SVC_CONFIG_NODE_ID, LSS_RESULT_SLAVE_ERROR, 8);
	TEST_ASSERT_EQUAL_UINT8(0xFF, last_done()->error_code);
	TEST_ASSERT_EQUAL_UINT8(0x33, last_done()->error_spec);
}

static void test_bit_timing_and_store_errors(void)
{
	TEST_ASSERT_EQUAL_INT(0, lss_master_config_bit_timing_req(mst.node, 0, 0, 1, 0));
	slave_says(0x13, 0x01, 0, 0, 0);
	expect_done(LSS_SVC_CONFIG_BIT_TIMING, LSS_RESULT_SLAVE_ERROR, 1);
	TEST_ASSERT_EQUAL_UINT8(LSS_EC_BIT_TIMING_UNSUPP, last_done()->error_code);

	TEST_ASSERT_EQUAL_INT(0, lss_master_store_req(mst.node, 2, 0));
	slave_says(0x17, 0x01, 0, 0, 0);
	expect_done(LSS_SVC_STORE, LSS_RESULT_SLAVE_ERROR, 2);
	TEST_ASSERT_EQUAL_UINT8(1, last_done()->error_code);
	TEST_ASSERT_EQUAL_STRING("store configuration not supported",
				 lss_error_to_string(LSS_CS_STORE, 1));

	TEST_ASSERT_EQUAL_INT(0, lss_master_store_req(mst.node, 3, 0));
	slave_says(0x17, 0x02, 0, 0, 0);
	expect_done(LSS_SVC_STORE, LSS_RESULT_SLAVE_ERROR, 3);
	TEST_ASSERT_EQUAL_UINT8(2, last_done()->error_code);
	TEST_ASSERT_EQUAL_STRING("storage media access error",
				 lss_error_to_string(LSS_CS_STORE, 2));
}

static void test_inquire_identity(void)
{
	static const struct {
		lss_master_service svc;
		uint8_t cs;
		uint32_t v;
	} q[] = {
		{ LSS_SVC_INQUIRE_VENDOR, 0x5A, 0x00000250 },
		{ LSS_SVC_INQUIRE_PRODUCT, 0x5B, 0x11223344 },
		{ LSS_SVC_INQUIRE_REVISION, 0x5C, 0x00010002 },
		{ LSS_SVC_INQUIRE_SERIAL, 0x5D, 123456 },
	};

	for (unsigned i = 0; i < 4; i++) {
		const uint8_t req[8] = { q[i].cs, 0, 0, 0, 0, 0, 0, 0 };
		unsigned at = n_tx();

		TEST_ASSERT_EQUAL_INT(0, lss_master_inquire_req(mst.node, q[i].svc, 100 + i, 0));
		lss_fixture_expect_frame(&bus, at, 0x7E5, req);
		slave_says(q[i].cs, (uint8_t)q[i].v, (uint8_t)(q[i].v >> 8),
			   (uint8_t)(q[i].v >> 16), (uint8_t)(q[i].v >> 24));
		expect_done(q[i].svc, LSS_RESULT_OK, 100 + i);
		TEST_ASSERT_EQUAL_HEX32(q[i].v, last_done()->value);
	}
	TEST_ASSERT_EQUAL_INT(-EINVAL, lss_master_inquire_req(mst.node, LSS_SVC_STORE, 1, 0));
}

/* ---- time ---------------------------------------------------------------------------- */

static void test_confirmed_service_times_out_by_the_clock(void)
{
	TEST_ASSERT_EQUAL_INT(0, lss_master_store_req(mst.node, 9, 5 * MS));
	TEST_ASSERT_EQUAL_UINT64(1005 * MS, deadline());
	tb_advance_to(&bus, 1005 * MS - 1);
	TEST_ASSERT_EQUAL_UINT(0, n_done());
	tb_advance_to(&bus, 1005 * MS);
	TEST_ASSERT_EQUAL_UINT(1, n_done());
	expect_done(LSS_SVC_STORE, LSS_RESULT_TIMEOUT, 9);
	TEST_ASSERT_EQUAL_UINT64(1005 * MS, mst.ev.ev[mst.ev.n - 1].now_us);
	/* A late answer is ignored (master idle). */
	slave_says(0x17, 0, 0, 0, 0);
	TEST_ASSERT_EQUAL_UINT(1, n_done());

	/* Per-request timeout. */
	lss_master_req r = { .service = LSS_SVC_INQUIRE_SERIAL, .tag = 10, .timeout_ms = 20 };
	TEST_ASSERT_EQUAL_INT(0, lss_master_submit(mst.node, &r, bus.now));
	tb_advance(&bus, 19 * MS);
	TEST_ASSERT_EQUAL_UINT(1, n_done());
	tb_advance(&bus, 1 * MS);
	expect_done(LSS_SVC_INQUIRE_SERIAL, LSS_RESULT_TIMEOUT, 10);
}

static void test_configured_default_timeout(void)
{
	co_node_config c = master_cfg();

	tb_fini(&bus);
	lss_bus_init(&bus);
	c.lss_timeout_ms = 250;
	TEST_ASSERT_EQUAL_INT(0, lss_fixture_create(&mst, &bus, &c, NULL));
	TEST_ASSERT_EQUAL_INT(0, lss_master_config_node_id_req(mst.node, 3, 1, 0));
	TEST_ASSERT_EQUAL_UINT64(250 * MS, deadline());
	tb_advance_to(&bus, 250 * MS);
	expect_done(LSS_SVC_CONFIG_NODE_ID, LSS_RESULT_TIMEOUT, 1);
}

static void test_wrong_answers_are_ignored(void)
{
	TEST_ASSERT_EQUAL_INT(0, lss_master_store_req(mst.node, 1, 0));
	slave_says(0x11, 0x00, 0, 0, 0); /* answer of another service */
	slave_says(0x44, 0, 0, 0, 0);
	TEST_ASSERT_EQUAL_UINT(0, n_done());
	/* A short answer without error code is not an answer. */
	co_frame f;
	co_frame_init(&f, LSS_COBID_SLAVE, 1);
	f.data[0] = 0x17;
	co_node_recv(mst.node, &f, 0);
	TEST_ASSERT_EQUAL_UINT(0, n_done());
	slave_says(0x17, 0x00, 0, 0, 0);
	expect_done(LSS_SVC_STORE, LSS_RESULT_OK, 1);
}

static void test_activate_bit_timing_holds_the_bus(void)
{
	const uint8_t act[8] = { 0x15, 0xE8, 0x03, 0, 0, 0, 0, 0 }; /* 1000 ms */

	TEST_ASSERT_EQUAL_INT(LSS_MASTER_IDLE, lss_master_state_of(mst.node));
	TEST_ASSERT_EQUAL_INT(0, lss_master_activate_bit_timing_req(mst.node, 1000, 1, 0));
	TEST_ASSERT_EQUAL_INT(LSS_MASTER_ACTIVATE, lss_master_state_of(mst.node));
	TEST_ASSERT_EQUAL_INT(0, lss_master_switch_global_req(mst.node, LSS_STATE_WAITING, 2, 0));
	lss_fixture_expect_frame(&bus, 0, 0x7E5, act);
	TEST_ASSERT_EQUAL_UINT(1, n_tx());
	tb_advance_to(&bus, 999 * MS);
	TEST_ASSERT_EQUAL_UINT(0, n_done());
	tb_advance_to(&bus, 1000 * MS);
	TEST_ASSERT_EQUAL_UINT(1, n_done());
	expect_done(LSS_SVC_ACTIVATE_BIT_TIMING, LSS_RESULT_OK, 1);
	/* Second delay: the next request waits until 2000 ms. */
	TEST_ASSERT_EQUAL_UINT(1, n_tx());
	TEST_ASSERT_EQUAL_UINT64(2000 * MS, deadline());
	tb_advance_to(&bus, 1999 * MS);
	TEST_ASSERT_EQUAL_UINT(1, n_tx());
	TEST_ASSERT_EQUAL_INT(LSS_MASTER_IDLE, lss_master_state_of(mst.node));
	tb_advance_to(&bus, 2000 * MS);
	TEST_ASSERT_EQUAL_UINT(2, n_tx());
	expect_done(LSS_SVC_SWITCH_GLOBAL, LSS_RESULT_OK, 2);
	TEST_ASSERT_EQUAL_INT(LSS_MASTER_IDLE, lss_master_state_of(mst.node));
	TEST_ASSERT_EQUAL_UINT64(2000 * MS, tx_time(1));
}

/* ---- identify ---------------------------------------------------------------------------- */

static void test_identify_remote_frames_and_window(void)
{
	const lss_address lo = { { 0x250, 0x10, 0x00010000, 100 } };
	const lss_address hi = { { 0, 0, 0x0001FFFF, 200 } };
	const uint8_t want[6][8] = {
		{ 0x46, 0x50, 0x02, 0x00, 0x00 }, { 0x47, 0x10, 0, 0, 0 },
		{ 0x48, 0x00, 0x00, 0x01, 0x00 }, { 0x49, 0xFF, 0xFF, 0x01, 0x00 },
		{ 0x4A, 100, 0, 0, 0 },           { 0x4B, 200, 0, 0, 0 },
	};

	TEST_ASSERT_EQUAL_INT(0, lss_master_identify_remote_req(mst.node, &lo, &hi, 5, 0));
	TEST_ASSERT_EQUAL_UINT(6, n_tx());
	for (unsigned i = 0; i < 6; i++)
		lss_fixture_expect_frame(&bus, i, 0x7E5, want[i]);
	tb_advance_to(&bus, 3 * MS);
	slave_says(0x4F, 0, 0, 0, 0);
	slave_says(0x4F, 0, 0, 0, 0);
	slave_says(0x50, 0, 0, 0, 0);        /* not ours */
	TEST_ASSERT_EQUAL_UINT(0, n_done()); /* the window stays open */
	tb_advance_to(&bus, 1000 * MS);
	expect_done(LSS_SVC_IDENTIFY_REMOTE, LSS_RESULT_OK, 5);
	TEST_ASSERT_EQUAL_UINT16(2, last_done()->answers);

	/* Nobody: NOT_FOUND, not an error. */
	TEST_ASSERT_EQUAL_INT(0, lss_master_identify_remote_req(mst.node, &lo, &hi, 6, bus.now));
	tb_advance(&bus, 1000 * MS);
	expect_done(LSS_SVC_IDENTIFY_REMOTE, LSS_RESULT_NOT_FOUND, 6);
	TEST_ASSERT_EQUAL_UINT16(0, last_done()->answers);
}

static void test_identify_non_configured(void)
{
	const uint8_t req[8] = { 0x4C, 0, 0, 0, 0, 0, 0, 0 };
	lss_master_req r = { .service = LSS_SVC_IDENTIFY_NON_CONFIGURED,
			     .tag = 3,
			     .timeout_ms = 50 };

	TEST_ASSERT_EQUAL_INT(0, lss_master_submit(mst.node, &r, 0));
	lss_fixture_expect_frame(&bus, 0, 0x7E5, req);
	slave_says(0x50, 0, 0, 0, 0);
	tb_advance_to(&bus, 49 * MS);
	TEST_ASSERT_EQUAL_UINT(0, n_done());
	tb_advance_to(&bus, 50 * MS);
	expect_done(LSS_SVC_IDENTIFY_NON_CONFIGURED, LSS_RESULT_OK, 3);
	TEST_ASSERT_EQUAL_UINT16(1, last_done()->answers);
}

/* ---- queue, cancel, failures ------------------------------------------------------------ */

static void test_queue_is_fifo_and_bounded(void)
{
	co_node_config c = master_cfg();

	tb_fini(&bus);
	lss_bus_init(&bus);
	c.lss_queue_len = 2;
	TEST_ASSERT_EQUAL_INT(0, lss_fixture_create(&mst, &bus, &c, NULL));

	TEST_ASSERT_EQUAL_INT(0, lss_master_store_req(mst.node, 1, 0)); /* runs */
	TEST_ASSERT_EQUAL_INT(0, lss_master_config_node_id_req(mst.node, 4, 2, 0));
	TEST_ASSERT_EQUAL_INT(0, lss_master_inquire_req(mst.node, LSS_SVC_INQUIRE_NODE_ID, 3, 0));
	TEST_ASSERT_EQUAL_INT(-ENOSPC, lss_master_store_req(mst.node, 4, 0));
	TEST_ASSERT_EQUAL_UINT(3, lss_master_pending(mst.node));
	/* One service on the bus at a time. */
	TEST_ASSERT_EQUAL_UINT(1, n_tx());
	TEST_ASSERT_EQUAL_HEX8(0x17, tx(0)->data[0]);

	slave_says(0x17, 0, 0, 0, 0);
	expect_done(LSS_SVC_STORE, LSS_RESULT_OK, 1);
	TEST_ASSERT_EQUAL_UINT(2, n_tx());
	TEST_ASSERT_EQUAL_HEX8(0x11, tx(1)->data[0]);
	slave_says(0x11, 0, 0, 0, 0);
	expect_done(LSS_SVC_CONFIG_NODE_ID, LSS_RESULT_OK, 2);
	TEST_ASSERT_EQUAL_HEX8(0x5E, tx(2)->data[0]);
	slave_says(0x5E, 4, 0, 0, 0);
	expect_done(LSS_SVC_INQUIRE_NODE_ID, LSS_RESULT_OK, 3);
	TEST_ASSERT_EQUAL_UINT(3, n_done());
	TEST_ASSERT_EQUAL_UINT(0, lss_master_pending(mst.node));
}

static void test_cancel_all(void)
{
	TEST_ASSERT_EQUAL_INT(0, lss_master_store_req(mst.node, 1, 0));
	TEST_ASSERT_EQUAL_INT(0, lss_master_store_req(mst.node, 2, 0));
	TEST_ASSERT_EQUAL_INT(0, lss_master_store_req(mst.node, 3, 0));
	lss_master_cancel_all(mst.node, 7 * MS);
	TEST_ASSERT_EQUAL_UINT(3, n_done());
	for (unsigned i = 0; i < 3; i++) {
		const co_ev_lss_master *d = &mst.ev.ev[i].u.lss_master;
		TEST_ASSERT_EQUAL_UINT8(LSS_RESULT_CANCELLED, d->result);
		TEST_ASSERT_EQUAL_UINT64(i + 1, d->tag);
		TEST_ASSERT_EQUAL_UINT64(7 * MS, mst.ev.ev[i].now_us);
	}
	TEST_ASSERT_EQUAL_UINT(1, n_tx()); /* the queued ones never went out */
	TEST_ASSERT_EQUAL_UINT(0, lss_master_pending(mst.node));
	TEST_ASSERT_EQUAL_UINT64(CO_NO_DEADLINE, deadline());
}

static void test_tx_failure_completes_the_request(void)
{
	bus.fail_send = true;
	TEST_ASSERT_EQUAL_INT(0, lss_master_switch_selective_req(
					 mst.node, &(lss_address){ { 1, 2, 3, 4 } }, 1, 0));
	TEST_ASSERT_EQUAL_UINT(1, evlog_count(&mst.ev, CO_EV_TX_FAILED)); /* stops at the first */
	co_node_tick(mst.node, bus.now); /* confirmed by the next tick, never inside the request */
	expect_done(LSS_SVC_SWITCH_SELECTIVE, LSS_RESULT_TX_FAILED, 1);
	TEST_ASSERT_EQUAL_UINT(0, lss_master_pending(mst.node));
}

static void test_bad_requests(void)
{
	lss_master_req r = { .service = LSS_SVC_SWITCH_GLOBAL, .mode = 2 };
	lss_fixture s;
	co_node_config c = { .node_id = 3 };

	TEST_ASSERT_EQUAL_INT(-EINVAL, lss_master_submit(mst.node, &r, 0));
	r.service = LSS_SVC_COUNT;
	TEST_ASSERT_EQUAL_INT(-EINVAL, lss_master_submit(mst.node, &r, 0));
	r.service = LSS_SVC_NONE;
	TEST_ASSERT_EQUAL_INT(-EINVAL, lss_master_submit(mst.node, &r, 0));
	TEST_ASSERT_EQUAL_INT(-EINVAL, lss_master_fastscan_req(mst.node, NULL, 1, 0, 0));
	TEST_ASSERT_EQUAL_INT(
		-EINVAL, lss_master_fastscan_req(mst.node, &(lss_address){ { 0 } }, 0x10, 0, 0));
	TEST_ASSERT_EQUAL_UINT(0, n_tx());
	/* A node without LSS master. */
	TEST_ASSERT_EQUAL_INT(0, lss_fixture_create(&s, &bus, &c, NULL));
	TEST_ASSERT_EQUAL_INT(-ENODEV, lss_master_store_req(s.node, 1, 0));
	TEST_ASSERT_EQUAL_UINT(0, lss_master_pending(s.node));
}

static void test_names(void)
{
	TEST_ASSERT_EQUAL_STRING("switch-selective-serial", lss_cs_to_string(0x43));
	TEST_ASSERT_EQUAL_STRING("fastscan", lss_cs_to_string(0x51));
	TEST_ASSERT_EQUAL_STRING("inquire-node-id", lss_cs_to_string(0x5E));
	TEST_ASSERT_EQUAL_STRING("?", lss_cs_to_string(0x99));
	TEST_ASSERT_EQUAL_STRING("configuration", lss_state_to_string(LSS_STATE_CONFIGURATION));
	TEST_ASSERT_EQUAL_STRING("fastscan", lss_master_service_to_string(LSS_SVC_FASTSCAN));
	TEST_ASSERT_EQUAL_STRING("timeout", lss_result_to_string(LSS_RESULT_TIMEOUT));
	TEST_ASSERT_EQUAL_STRING("lss-master-done", co_event_kind_to_string(CO_EV_LSS_MASTER_DONE));
	TEST_ASSERT_EQUAL_UINT16(125, lss_bit_rate_kbit(4));
	TEST_ASSERT_EQUAL_UINT16(0, lss_bit_rate_kbit(5));
	TEST_ASSERT_EQUAL_UINT16(10, lss_bit_rate_kbit(8));
	TEST_ASSERT_EQUAL_UINT16(0, lss_bit_rate_kbit(9));
	TEST_ASSERT_EQUAL_STRING("fs-confirm", lss_master_state_to_string(LSS_MASTER_FS_CONFIRM));
	TEST_ASSERT_EQUAL_STRING("done-later", lss_master_state_to_string(LSS_MASTER_DONE_LATER));
	TEST_ASSERT_EQUAL_STRING("?", lss_master_state_to_string(LSS_MASTER_STATE_COUNT));
}

/* ---- per-request confirmation ------------------------------------------------ */

static struct {
	unsigned n;
	co_ev_lss_master last;
	bool in_submit;
	unsigned during_submit;
} cons;

static void on_con(void *arg, const co_ev_lss_master *con)
{
	TEST_ASSERT_EQUAL_PTR(&cons, arg);
	cons.during_submit += cons.in_submit;
	cons.last = *con;
	cons.n++;
}

static int submit_with_con(lss_master_req r)
{
	int rc;

	r.con = on_con;
	r.con_arg = &cons;
	cons.in_submit = true;
	rc = lss_master_submit(mst.node, &r, bus.now);
	cons.in_submit = false;
	return rc;
}

static void test_confirmation_once_never_inside_submit(void)
{
	memset(&cons, 0, sizeof(cons));
	/* Unconfirmed service: done once out, confirmed at the next tick. */
	TEST_ASSERT_EQUAL_INT(0, submit_with_con((lss_master_req){ .service = LSS_SVC_SWITCH_GLOBAL,
								   .mode = LSS_STATE_CONFIGURATION,
								   .tag = 1 }));
	TEST_ASSERT_EQUAL_UINT(0, cons.n);
	TEST_ASSERT_EQUAL_UINT(0, n_done());
	TEST_ASSERT_TRUE(co_node_next_deadline_us(mst.node) <= bus.now);
	co_node_tick(mst.node, bus.now);
	TEST_ASSERT_EQUAL_UINT(1, cons.n);
	TEST_ASSERT_EQUAL_UINT64(1, cons.last.tag);
	TEST_ASSERT_EQUAL_UINT8(LSS_RESULT_OK, cons.last.result);
	TEST_ASSERT_EQUAL_UINT(1, n_done()); /* the event for observers too */

	/* Confirmed service: con with the slave's answer. */
	TEST_ASSERT_EQUAL_INT(0, submit_with_con((lss_master_req){
					 .service = LSS_SVC_INQUIRE_NODE_ID, .tag = 2 }));
	slave_says(0x5E, 0x21, 0, 0, 0);
	TEST_ASSERT_EQUAL_UINT(2, cons.n);
	TEST_ASSERT_EQUAL_UINT64(2, cons.last.tag);
	TEST_ASSERT_EQUAL_UINT8(0x21, cons.last.node_id);

	/* Cancelled: still exactly once. */
	TEST_ASSERT_EQUAL_INT(
		0, submit_with_con((lss_master_req){ .service = LSS_SVC_STORE, .tag = 3 }));
	TEST_ASSERT_EQUAL_INT(
		0, submit_with_con((lss_master_req){ .service = LSS_SVC_STORE, .tag = 4 }));
	lss_master_cancel_all(mst.node, bus.now);
	TEST_ASSERT_EQUAL_UINT(4, cons.n);
	TEST_ASSERT_EQUAL_UINT64(4, cons.last.tag);
	TEST_ASSERT_EQUAL_UINT8(LSS_RESULT_CANCELLED, cons.last.result);
	tb_advance_to(&bus, bus.now + 5000 * MS);
	TEST_ASSERT_EQUAL_UINT(4, cons.n);
	TEST_ASSERT_EQUAL_UINT(0, cons.during_submit);
	TEST_ASSERT_EQUAL_UINT(4, n_done());
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_golden_switch_selective_serial_123456);
	RUN_TEST(test_golden_configure_sequence);
	RUN_TEST(test_config_node_id_slave_errors);
	RUN_TEST(test_bit_timing_and_store_errors);
	RUN_TEST(test_inquire_identity);
	RUN_TEST(test_confirmed_service_times_out_by_the_clock);
	RUN_TEST(test_configured_default_timeout);
	RUN_TEST(test_wrong_answers_are_ignored);
	RUN_TEST(test_activate_bit_timing_holds_the_bus);
	RUN_TEST(test_identify_remote_frames_and_window);
	RUN_TEST(test_identify_non_configured);
	RUN_TEST(test_queue_is_fifo_and_bounded);
	RUN_TEST(test_cancel_all);
	RUN_TEST(test_tx_failure_completes_the_request);
	RUN_TEST(test_bad_requests);
	RUN_TEST(test_confirmation_once_never_inside_submit);
	RUN_TEST(test_names);
	return UNITY_END();
}
