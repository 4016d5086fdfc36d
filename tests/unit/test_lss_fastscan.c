/* SPDX-License-Identifier: MIT */
/*
 * LSS Fastscan: the master finds slaves with unknown identities bit by bit
 * (CiA 305 LSS Fastscan), against real LSS slaves wired in memory, and the
 * slave's side of the protocol against scripted probes.
 */
#include <errno.h>
#include <string.h>

#include "core/lss_master.h"
#include "core/lss_slave.h"
#include "tests/unit/support/lss_fixture.h"
#include "unity.h"

#define MS 1000u

static tb_bus bus;
static lss_fixture mst;
static lss_fixture slv[3];
static unsigned n_slv;

/* Deliberately awkward values: high bits set, runs of zeros and ones. */
static const lss_address unknown_a = { { 0x000004C3, 0x80000001, 0x00020003, 0xCAFE1234 } };
static const lss_address unknown_b = { { 0x000004C3, 0x80000001, 0x00020003, 0xCAFE1334 } };

/* Steps of a full scan: the reset, then per field 31 probes (bits 31..1)
 * and one confirmation, two when bit 0 is 1. */
static unsigned scan_steps(const lss_address *a)
{
	unsigned n = 1;

	for (unsigned i = 0; i < LSS_ID_COUNT; i++)
		n += 31 + 1 + (a->id[i] & 1u);
	return n;
}

static void add_slave(uint8_t node_id, const lss_address *id)
{
	co_node_config c = { .node_id = node_id, .lss_slave = true };

	TEST_ASSERT_EQUAL_INT(0, lss_fixture_create(&slv[n_slv++], &bus, &c, id));
}

void setUp(void)
{
	co_node_config c = { .node_id = 0x7F, .lss_master = true };

	lss_bus_init(&bus);
	n_slv = 0;
	TEST_ASSERT_EQUAL_INT(0, lss_fixture_create(&mst, &bus, &c, NULL));
}

void tearDown(void)
{
	tb_fini(&bus); /* the bus owns every node */
}

static const co_ev_lss_master *last_done(void)
{
	for (unsigned i = mst.ev.n; i-- > 0;)
		if (mst.ev.ev[i].kind == CO_EV_LSS_MASTER_DONE)
			return &mst.ev.ev[i].u.lss_master;
	TEST_FAIL_MESSAGE("no CO_EV_LSS_MASTER_DONE");
	return NULL;
}

static unsigned n_done(void)
{
	return evlog_count(&mst.ev, CO_EV_LSS_MASTER_DONE);
}

static lss_state slave_state(unsigned i)
{
	lss_state s;

	TEST_ASSERT_EQUAL_INT(0, lss_slave_get(slv[i].node, &s, NULL, NULL, NULL));
	return s;
}

static void expect_identity(const lss_address *want, const co_ev_lss_master *d)
{
	TEST_ASSERT_EQUAL_HEX32_ARRAY(want->id, d->identity, 4);
}

/* Run one request to completion; returns its result. */
static lss_result run(uint64_t max_us)
{
	unsigned before = n_done();

	tb_advance(&bus, max_us);
	TEST_ASSERT_EQUAL_UINT_MESSAGE(before + 1, n_done(), "request did not complete");
	return (lss_result)last_done()->result;
}

static unsigned fastscan_frames(void)
{
	unsigned n = 0;

	for (unsigned i = 0; i < tb_log_count(&bus); i++)
		n += tb_log_at(&bus, i)->id == LSS_COBID_MASTER &&
		     tb_log_at(&bus, i)->data[0] == LSS_CS_FASTSCAN;
	return n;
}

/* ---- Fastscan, then a node-ID ---------------------------------------------------------------------- */

static void test_fastscan_then_assign_node_id_5(void)
{
	uint64_t t0;

	add_slave(LSS_NODE_ID_UNCONFIGURED, &unknown_a);
	t0 = bus.now;
	TEST_ASSERT_EQUAL_INT(0, lss_master_fastscan_req(mst.node, NULL, 0, 54, t0));
	TEST_ASSERT_EQUAL_INT(LSS_RESULT_OK, run(20000 * MS));
	expect_identity(&unknown_a, last_done());
	TEST_ASSERT_EQUAL_UINT64(54, last_done()->tag);
	/* Every step listens for its whole 100 ms window. */
	TEST_ASSERT_EQUAL_UINT(132, scan_steps(&unknown_a));
	TEST_ASSERT_EQUAL_UINT(scan_steps(&unknown_a), fastscan_frames());
	TEST_ASSERT_EQUAL_UINT64(t0 + scan_steps(&unknown_a) * 100 * MS,
				 mst.ev.ev[mst.ev.n - 1].now_us);
	/* Every BitChecked-0 frame is a confirmation carrying the real
	 * LSSNext; probes never send BitChecked 0 (see lss_master.c). */
	for (unsigned i = 0; i < tb_log_count(&bus); i++) {
		const co_frame *f = tb_log_at(&bus, i);
		if (f->id != LSS_COBID_MASTER || f->data[0] != LSS_CS_FASTSCAN || f->data[5] != 0)
			continue;
		TEST_ASSERT_EQUAL_UINT8((f->data[6] + 1) % 4, f->data[7]);
	}
	/* The found slave was left in configuration state. */
	TEST_ASSERT_EQUAL_INT(LSS_STATE_CONFIGURATION, slave_state(0));

	/* Set ID -> error 0. */
	TEST_ASSERT_EQUAL_INT(0, lss_master_config_node_id_req(mst.node, 5, 1, bus.now));
	TEST_ASSERT_EQUAL_INT(LSS_RESULT_OK, run(1000 * MS));
	TEST_ASSERT_EQUAL_UINT8(0, last_done()->error_code);
	/* Store -> 0. */
	TEST_ASSERT_EQUAL_INT(0, lss_master_store_req(mst.node, 2, bus.now));
	TEST_ASSERT_EQUAL_INT(LSS_RESULT_OK, run(1000 * MS));
	TEST_ASSERT_EQUAL_UINT8(0, last_done()->error_code);
	TEST_ASSERT_EQUAL_UINT(1, evlog_count(&slv[0].ev, CO_EV_LSS_SLAVE_STORE));
	/* Invalid ID -> error 1, the good one stays pending. */
	TEST_ASSERT_EQUAL_INT(0, lss_master_config_node_id_req(mst.node, 0, 3, bus.now));
	TEST_ASSERT_EQUAL_INT(LSS_RESULT_SLAVE_ERROR, run(1000 * MS));
	TEST_ASSERT_EQUAL_UINT8(1, last_done()->error_code);
	TEST_ASSERT_EQUAL_INT(0, lss_master_config_node_id_req(mst.node, 128, 4, bus.now));
	TEST_ASSERT_EQUAL_INT(LSS_RESULT_SLAVE_ERROR, run(1000 * MS));
	TEST_ASSERT_EQUAL_UINT8(1, last_done()->error_code);

	/* Back to waiting: the slave applies id 5 by itself. */
	TEST_ASSERT_EQUAL_INT(
		0, lss_master_switch_global_req(mst.node, LSS_STATE_WAITING, 5, bus.now));
	co_node_tick(mst.node, bus.now); /* confirmed by the next tick, never inside the request */
	TEST_ASSERT_EQUAL_INT(LSS_RESULT_OK, (lss_result)last_done()->result);
	tb_pump(&bus);
	uint8_t a, p, s;
	TEST_ASSERT_EQUAL_INT(0, lss_slave_get(slv[0].node, NULL, &a, &p, &s));
	TEST_ASSERT_EQUAL_UINT8(5, a);
	TEST_ASSERT_EQUAL_UINT8(5, p);
	TEST_ASSERT_EQUAL_UINT8(5, s);
	TEST_ASSERT_EQUAL_UINT8(5, co_node_id(slv[0].node));
	/* Unconfigured, it never booted; with id 5 it boots as 705: 00 (the
	 * NMT service sends the boot-up at the tick after the reset). */
	TEST_ASSERT_EQUAL_UINT(0, tb_log_count_id(&bus, 0x705));
	tb_advance(&bus, 1 * MS);
	TEST_ASSERT_EQUAL_UINT(1, tb_log_count_id(&bus, 0x705));
	int b = tb_log_nth_id(&bus, 0x705, 0);
	TEST_ASSERT_EQUAL_UINT8(1, tb_log_at(&bus, b)->len);
	TEST_ASSERT_EQUAL_HEX8(0x00, tb_log_at(&bus, b)->data[0]);

	/* Configured now: a new scan finds nobody, after one step. */
	TEST_ASSERT_EQUAL_INT(0, lss_master_fastscan_req(mst.node, NULL, 0, 6, bus.now));
	TEST_ASSERT_EQUAL_INT(LSS_RESULT_NOT_FOUND, run(100 * MS));
}

static void test_two_unconfigured_slaves_found_one_at_a_time(void)
{
	uint8_t id;

	add_slave(LSS_NODE_ID_UNCONFIGURED, &unknown_b);
	add_slave(LSS_NODE_ID_UNCONFIGURED, &unknown_a);
	add_slave(3, &(lss_address){ { 0x000004C3, 0x80000001, 0x00020003, 0x00000001 } });

	/* The configured slave (id 3, lowest serial) never takes part; of the
	 * other two, the scan prefers 0 bits: A (..12..) before B (..13..). */
	TEST_ASSERT_EQUAL_INT(0, lss_master_fastscan_req(mst.node, NULL, 0, 1, bus.now));
	TEST_ASSERT_EQUAL_INT(LSS_RESULT_OK, run(20000 * MS));
	expect_identity(&unknown_a, last_done());
	TEST_ASSERT_EQUAL_INT(LSS_STATE_CONFIGURATION, slave_state(1));
	TEST_ASSERT_EQUAL_INT(LSS_STATE_WAITING, slave_state(0));
	TEST_ASSERT_EQUAL_INT(LSS_STATE_WAITING, slave_state(2));
	TEST_ASSERT_EQUAL_INT(0, lss_master_config_node_id_req(mst.node, 5, 2, bus.now));
	TEST_ASSERT_EQUAL_INT(LSS_RESULT_OK, run(1000 * MS));
	TEST_ASSERT_EQUAL_INT(
		0, lss_master_switch_global_req(mst.node, LSS_STATE_WAITING, 3, bus.now));
	tb_advance_to(&bus, bus.now);

	TEST_ASSERT_EQUAL_INT(0, lss_master_fastscan_req(mst.node, NULL, 0, 4, bus.now));
	TEST_ASSERT_EQUAL_INT(LSS_RESULT_OK, run(20000 * MS));
	expect_identity(&unknown_b, last_done());
	TEST_ASSERT_EQUAL_INT(LSS_STATE_CONFIGURATION, slave_state(0));
	TEST_ASSERT_EQUAL_INT(0, lss_master_config_node_id_req(mst.node, 6, 5, bus.now));
	TEST_ASSERT_EQUAL_INT(LSS_RESULT_OK, run(1000 * MS));
	TEST_ASSERT_EQUAL_INT(
		0, lss_master_switch_global_req(mst.node, LSS_STATE_WAITING, 6, bus.now));
	tb_advance_to(&bus, bus.now);

	TEST_ASSERT_EQUAL_INT(0, lss_slave_get(slv[0].node, NULL, &id, NULL, NULL));
	TEST_ASSERT_EQUAL_UINT8(6, id);
	TEST_ASSERT_EQUAL_INT(0, lss_slave_get(slv[1].node, NULL, &id, NULL, NULL));
	TEST_ASSERT_EQUAL_UINT8(5, id);
	TEST_ASSERT_EQUAL_INT(0, lss_slave_get(slv[2].node, NULL, &id, NULL, NULL));
	TEST_ASSERT_EQUAL_UINT8(3, id);

	/* Nobody left. */
	TEST_ASSERT_EQUAL_INT(0, lss_master_identify_non_configured_req(mst.node, 7, bus.now));
	TEST_ASSERT_EQUAL_INT(LSS_RESULT_NOT_FOUND, run(1000 * MS));
	TEST_ASSERT_EQUAL_INT(0, lss_master_fastscan_req(mst.node, NULL, 0, 8, bus.now));
	TEST_ASSERT_EQUAL_INT(LSS_RESULT_NOT_FOUND, run(100 * MS));
}

/* ---- variants ---------------------------------------------------------------------------- */

static void test_known_fields_are_only_confirmed(void)
{
	unsigned before;

	add_slave(LSS_NODE_ID_UNCONFIGURED, &unknown_a);
	before = fastscan_frames();
	/* Vendor, product and revision known: scan the serial only. */
	TEST_ASSERT_EQUAL_INT(0, lss_master_fastscan_req(mst.node, &unknown_a, 0x7, 1, bus.now));
	TEST_ASSERT_EQUAL_INT(LSS_RESULT_OK, run(20000 * MS));
	expect_identity(&unknown_a, last_done());
	TEST_ASSERT_EQUAL_UINT(1 + 3 + 32, fastscan_frames() - before); /* serial bit 0 is 0 */

	/* The confirmation frame of a known field carries the full value,
	 * BitChecked 0, LSSSub and LSSNext. */
	int i = tb_log_nth_id(&bus, LSS_COBID_MASTER, 2); /* after reset + vendor */
	const uint8_t product[8] = { 0x51, 0x01, 0x00, 0x00, 0x80, 0x00, 0x01, 0x02 };
	TEST_ASSERT_EQUAL_HEX8_ARRAY(product, tb_log_at(&bus, i)->data, 8);
}

static void test_known_value_nobody_has_is_not_found(void)
{
	lss_address wrong = unknown_a;

	add_slave(LSS_NODE_ID_UNCONFIGURED, &unknown_a);
	wrong.id[LSS_ID_VENDOR] = 0x999;
	TEST_ASSERT_EQUAL_INT(0, lss_master_fastscan_req(mst.node, &wrong, 0x1, 1, bus.now));
	TEST_ASSERT_EQUAL_INT(LSS_RESULT_NOT_FOUND, run(200 * MS));
	TEST_ASSERT_EQUAL_INT(LSS_STATE_WAITING, slave_state(0));
}

static void test_no_slave_and_custom_step_timeout(void)
{
	lss_master_req r = { .service = LSS_SVC_FASTSCAN, .tag = 9, .timeout_ms = 10 };
	const uint8_t reset[8] = { 0x51, 0, 0, 0, 0, 0x80, 0, 0 };

	TEST_ASSERT_EQUAL_INT(0, lss_master_submit(mst.node, &r, 0));
	lss_fixture_expect_frame(&bus, 0, LSS_COBID_MASTER, reset);
	tb_advance_to(&bus, 9 * MS);
	TEST_ASSERT_EQUAL_UINT(0, n_done());
	tb_advance_to(&bus, 10 * MS);
	TEST_ASSERT_EQUAL_UINT(1, n_done());
	TEST_ASSERT_EQUAL_UINT8(LSS_RESULT_NOT_FOUND, last_done()->result);
	TEST_ASSERT_EQUAL_UINT(1, fastscan_frames());

	/* With a slave and 10 ms steps the whole scan takes 132 x 10 ms. */
	add_slave(LSS_NODE_ID_UNCONFIGURED, &unknown_b);
	uint64_t t0 = bus.now;
	TEST_ASSERT_EQUAL_INT(0, lss_master_submit(mst.node, &r, t0));
	tb_advance_to(&bus, t0 + scan_steps(&unknown_b) * 10 * MS - 1);
	TEST_ASSERT_EQUAL_UINT(1, n_done());
	tb_advance_to(&bus, t0 + scan_steps(&unknown_b) * 10 * MS);
	TEST_ASSERT_EQUAL_UINT(2, n_done());
	TEST_ASSERT_EQUAL_UINT8(LSS_RESULT_OK, last_done()->result);
	expect_identity(&unknown_b, last_done());
}

static void test_slave_lost_mid_scan(void)
{
	/* A scripted slave answers the reset step, then goes silent: every
	 * probe reads as 1 and both confirmations (bit 0 = 0, then 1) go
	 * unanswered: 1 + 31 + 2 steps. */
	const uint8_t hello[8] = { 0x4F, 0, 0, 0, 0, 0, 0, 0 };

	TEST_ASSERT_EQUAL_INT(0, lss_master_fastscan_req(mst.node, NULL, 0, 1, 0));
	lss_bus_inject(&bus, LSS_COBID_SLAVE, hello);
	tb_advance_to(&bus, 34 * 100 * MS);
	TEST_ASSERT_EQUAL_UINT(1, n_done());
	TEST_ASSERT_EQUAL_UINT8(LSS_RESULT_SCAN_LOST, last_done()->result);
	TEST_ASSERT_EQUAL_HEX32(0xFFFFFFFF, last_done()->identity[0]);
}

/* ---- the slave's side, probe by probe ------------------------------------------------------ */

static void probe(uint32_t id, uint8_t bit, uint8_t sub, uint8_t next)
{
	const uint8_t d[8] = { 0x51,
			       (uint8_t)id,
			       (uint8_t)(id >> 8),
			       (uint8_t)(id >> 16),
			       (uint8_t)(id >> 24),
			       bit,
			       sub,
			       next };

	lss_bus_inject(&bus, LSS_COBID_MASTER, d);
}

static void test_slave_fastscan_protocol(void)
{
	unsigned n;

	add_slave(LSS_NODE_ID_UNCONFIGURED, &unknown_a);
#define ANSWERS tb_log_count_id(&bus, LSS_COBID_SLAVE)
	probe(0, 0x80, 0, 0);
	TEST_ASSERT_EQUAL_UINT(1, ANSWERS);
	n = ANSWERS;
	probe(0x00000000, 31, 0, 0); /* vendor bit 31 is 0: answer */
	TEST_ASSERT_EQUAL_UINT(++n, ANSWERS);
	probe(0x00000000, 10, 0, 0); /* bit 10 of 0x4C3 is 1: silent */
	TEST_ASSERT_EQUAL_UINT(n, ANSWERS);
	probe(0x00000400, 10, 0, 0);
	TEST_ASSERT_EQUAL_UINT(++n, ANSWERS);
	probe(0x000004C3, 0, 1, 2); /* wrong LSSSub for the position: silent */
	TEST_ASSERT_EQUAL_UINT(n, ANSWERS);
	probe(0x000004C2, 0, 0, 1); /* bit 0 wrong: silent */
	TEST_ASSERT_EQUAL_UINT(n, ANSWERS);
	probe(0x000004C3, 0, 0, 1); /* full vendor: answer, move to product */
	TEST_ASSERT_EQUAL_UINT(++n, ANSWERS);
	probe(0x000004C3, 0, 0, 1); /* position is 1 now */
	TEST_ASSERT_EQUAL_UINT(n, ANSWERS);
	probe(0x80000001, 0, 1, 2);
	probe(0x00020003, 0, 2, 3);
	n += 2;
	TEST_ASSERT_EQUAL_UINT(n, ANSWERS);
	TEST_ASSERT_EQUAL_INT(LSS_STATE_WAITING, slave_state(0));
	probe(0xCAFE1234, 0, 3, 0); /* LSSNext < LSSSub: configuration */
	TEST_ASSERT_EQUAL_UINT(++n, ANSWERS);
	TEST_ASSERT_EQUAL_INT(LSS_STATE_CONFIGURATION, slave_state(0));
	/* In configuration state Fastscan is ignored, even the reset. */
	probe(0, 0x80, 0, 0);
	TEST_ASSERT_EQUAL_UINT(n, ANSWERS);
	/* Malformed: BitChecked 32..7F, LSSSub/LSSNext > 3. */
	lss_master_switch_global_req(mst.node, LSS_STATE_WAITING, 0, bus.now);
	tb_pump(&bus);
	probe(0, 0x80, 0, 0);
	TEST_ASSERT_EQUAL_UINT(++n, ANSWERS);
	probe(0, 32, 0, 0);
	probe(0, 0, 4, 0);
	probe(0x000004C3, 0, 0, 4);
	TEST_ASSERT_EQUAL_UINT(n, ANSWERS);
#undef ANSWERS
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_fastscan_then_assign_node_id_5);
	RUN_TEST(test_two_unconfigured_slaves_found_one_at_a_time);
	RUN_TEST(test_known_fields_are_only_confirmed);
	RUN_TEST(test_known_value_nobody_has_is_not_found);
	RUN_TEST(test_no_slave_and_custom_step_timeout);
	RUN_TEST(test_slave_lost_mid_scan);
	RUN_TEST(test_slave_fastscan_protocol);
	return UNITY_END();
}
