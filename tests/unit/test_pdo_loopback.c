/* SPDX-License-Identifier: MIT */
/*
 * End-to-end PDO loopback: two core instances on the in-memory bus.
 *
 *   master (id 1): SDO client, NMT master, SYNC producer, RPDO 1..3
 *   slave  (id 5): SDO server, TPDO 1..3 (present but invalid, unmapped)
 *
 * The master maps the slave's TPDOs over SDO with the CiA 301 5-step
 * sequence, starts the network with NMT and receives the slave's objects:
 * under SYNC (TT 1 and TT 3) and event-driven (TT 254 with inhibit time and
 * event timer). The test owns the clock; nothing sleeps.
 */
#include <string.h>

#include "unity.h"

#include "core/nmt.h"
#include "core/pdo.h"
#include "core/sdo_client.h"
#include "core/sync.h"
#include "tests/unit/support/test_bus.h"

#define MASTER 1
#define SLAVE 5

static tb_bus bus;
static tb_port *mp, *sp; /* master, slave ports */
static co_node *master, *slave;
static co_od *mod, *sod;

/* SDO download buffers must live until completion. */
static uint8_t dl_buf[64][4];
static unsigned dl_n;

static co_od *slave_od(void)
{
	co_od *o;

	TEST_ASSERT_EQUAL(0, co_od_create(&o, 64));
	TEST_ASSERT_EQUAL(0,
			  co_od_add_num(o, 0x2000, 0, CO_T_UNSIGNED16, CO_ACC_RWR, 0x1234, NULL));
	TEST_ASSERT_EQUAL(0, co_od_add_num(o, 0x2001, 0, CO_T_UNSIGNED8, CO_ACC_RWR, 0x56, NULL));
	TEST_ASSERT_EQUAL(
		0, co_od_add_num(o, 0x2002, 0, CO_T_UNSIGNED32, CO_ACC_RWR, 0xCAFEF00D, NULL));
	TEST_ASSERT_EQUAL(0, co_od_add_comm_defaults_sync(o, 0, 0, 0));
	for (uint16_t n = 1; n <= 3; n++) {
		co_pdo_desc t = { .dir = CO_PDO_TX,
				  .nr = n,
				  .cob_id = CO_PDO_COB_INVALID | CO_PDO_TPDO_DEFAULT_COB(n, SLAVE),
				  .tt = 254 };
		TEST_ASSERT_EQUAL(0, co_od_add_pdo(o, &t));
	}
	return o;
}

static co_od *master_od(void)
{
	co_od *o;
	const uint32_t m1[] = { CO_PDO_MAP(0x3000, 0, 16), CO_PDO_MAP(0x3001, 0, 8) };
	const uint32_t m2[] = { CO_PDO_MAP(0x3002, 0, 32) };
	const uint32_t m3[] = { CO_PDO_MAP(0x3003, 0, 16) };
	co_pdo_desc r[3] = {
		{ .dir = CO_PDO_RX,
		  .nr = 1,
		  .cob_id = CO_PDO_TPDO_DEFAULT_COB(1, SLAVE),
		  .tt = 254,
		  .n_map = 2,
		  .map = m1 },
		{ .dir = CO_PDO_RX,
		  .nr = 2,
		  .cob_id = CO_PDO_TPDO_DEFAULT_COB(2, SLAVE),
		  .tt = 254,
		  .n_map = 1,
		  .map = m2 },
		{ .dir = CO_PDO_RX,
		  .nr = 3,
		  .cob_id = CO_PDO_TPDO_DEFAULT_COB(3, SLAVE),
		  .tt = 254,
		  .n_map = 1,
		  .map = m3 },
	};

	TEST_ASSERT_EQUAL(0, co_od_create(&o, 64));
	TEST_ASSERT_EQUAL(0, co_od_add_num(o, 0x3000, 0, CO_T_UNSIGNED16, CO_ACC_RWW, 0, NULL));
	TEST_ASSERT_EQUAL(0, co_od_add_num(o, 0x3001, 0, CO_T_UNSIGNED8, CO_ACC_RWW, 0, NULL));
	TEST_ASSERT_EQUAL(0, co_od_add_num(o, 0x3002, 0, CO_T_UNSIGNED32, CO_ACC_RWW, 0, NULL));
	TEST_ASSERT_EQUAL(0, co_od_add_num(o, 0x3003, 0, CO_T_UNSIGNED16, CO_ACC_RWW, 0, NULL));
	TEST_ASSERT_EQUAL(0, co_od_add_comm_defaults_sync(o, CO_SYNC_PRODUCER | 0x80, 0, 0));
	for (int i = 0; i < 3; i++)
		TEST_ASSERT_EQUAL(0, co_od_add_pdo(o, &r[i]));
	return o;
}

void setUp(void)
{
	co_node_config mc = { .node_id = MASTER,
			      .sdo_client_count = 1,
			      .sdo_client_queue_len = 16 };
	co_node_config sc = { .node_id = SLAVE };

	tb_init(&bus);
	dl_n = 0;
	mod = master_od();
	sod = slave_od();
	mp = tb_add_node(&bus, &mc, mod);
	sp = tb_add_node(&bus, &sc, sod);
	TEST_ASSERT_NOT_NULL(mp);
	TEST_ASSERT_NOT_NULL(sp);
	master = mp->node;
	slave = sp->node;
	tb_advance(&bus, 0); /* both boot into PRE-OPERATIONAL */
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_PRE_OPERATIONAL, co_nmt_get_state(slave));
	tb_log_clear(&bus);
	tb_events_clear(mp);
	tb_events_clear(sp);
}

void tearDown(void)
{
	tb_fini(&bus);
}

/* ---- helpers ------------------------------------------------------------------- */

static void sdo_dl(uint16_t index, uint8_t sub, uint32_t v, uint8_t size)
{
	uint8_t *b;

	TEST_ASSERT_TRUE(dl_n < 64);
	b = dl_buf[dl_n++];
	co_put_le32(b, v);
	TEST_ASSERT_EQUAL(
		0, sdo_client_write(master, 0, SLAVE, index, sub, b, size, 500, dl_n, bus.now));
}

/* Run the bus until the master's SDO queue is empty; return the number of
 * completions since the events were last cleared, asserting each one. */
static void sdo_finish(unsigned expect_done, uint32_t last_abort)
{
	unsigned done = 0;
	const co_event *last = NULL;

	tb_settle(&bus, 100000);
	TEST_ASSERT_EQUAL(0, sdo_client_pending(master, 0));
	for (size_t i = 0; i < mp->n_ev; i++) {
		if (mp->ev[i].kind != CO_EV_SDO_CLIENT_DONE)
			continue;
		last = &mp->ev[i];
		done++;
		if (done < expect_done)
			TEST_ASSERT_EQUAL_HEX32(0, last->u.sdo_cli.abort);
	}
	TEST_ASSERT_EQUAL(expect_done, done);
	TEST_ASSERT_EQUAL_HEX32(last_abort, last->u.sdo_cli.abort);
	tb_events_clear(mp);
}

/* The CiA 301 remap sequence over SDO (7 downloads). */
static void remote_map_tpdo(uint16_t nr, uint8_t tt, uint16_t inhibit, uint16_t event_ms, uint8_t n,
			    const uint32_t *map)
{
	uint16_t comm = (uint16_t)(0x1800 + nr - 1), mapi = (uint16_t)(0x1A00 + nr - 1);
	uint32_t cob = CO_PDO_TPDO_DEFAULT_COB(nr, SLAVE);
	unsigned reqs = 0;

	sdo_dl(comm, 1, CO_PDO_COB_INVALID | cob, 4), reqs++; /* 1 */
	sdo_dl(mapi, 0, 0, 1), reqs++;                        /* 2 */
	for (uint8_t i = 0; i < n; i++)
		sdo_dl(mapi, (uint8_t)(i + 1), map[i], 4), reqs++; /* 3 */
	sdo_dl(mapi, 0, n, 1), reqs++;                             /* 4 */
	sdo_dl(comm, 2, tt, 1), reqs++;
	sdo_dl(comm, 3, inhibit, 2), reqs++;
	sdo_dl(comm, 5, event_ms, 2), reqs++;
	sdo_dl(comm, 1, cob, 4), reqs++; /* 5 */
	sdo_finish(reqs, 0);
	TEST_ASSERT_TRUE(co_pdo_is_valid(slave, CO_PDO_TX, nr));
}

static void start_network(void)
{
	TEST_ASSERT_EQUAL(
		0, co_nmt_master_send_ex(master, 0, CO_NMT_CS_START, CO_NMT_SEND_SELF, bus.now));
	tb_settle(&bus, 1000);
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, co_nmt_get_state(slave));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, co_nmt_get_state(master));
}

static uint32_t local_write(co_node *n, co_od *o, uint16_t index, uint8_t sub, uint32_t v)
{
	co_od_entry *e = co_od_find(o, index, sub);
	co_od_access a = { .origin = CO_OD_ORIGIN_LOCAL };
	uint8_t b[4];

	co_put_le32(b, v);
	co_node_tick(n, bus.now);
	return co_od_write(e, b, e->size, &a);
}

static uint64_t val(co_od *o, uint16_t index)
{
	return co_od_entry_raw(co_od_find(o, index, 0));
}

static unsigned from_slave(uint32_t id, size_t since)
{
	unsigned k = 0;

	for (size_t i = since; i < tb_log_count(&bus); i++)
		if (tb_log_at(&bus, i)->id == id && bus.log_from[i] == sp->idx)
			k++;
	return k;
}

/* ---- scenarios ------------------------------------------------------------------ */

static void test_remap_over_sdo_then_sync_tt1(void)
{
	const uint32_t map[] = { CO_PDO_MAP(0x2000, 0, 16), CO_PDO_MAP(0x2001, 0, 8) };
	size_t mark;

	remote_map_tpdo(1, 1, 0, 0, 2, map);
	/* the slave's OD says what the master wrote */
	TEST_ASSERT_EQUAL_HEX64(2, val(sod, 0x1A00));
	TEST_ASSERT_EQUAL_HEX64(CO_PDO_MAP(0x2001, 0, 8),
				co_od_entry_raw(co_od_find(sod, 0x1A00, 2)));
	start_network();
	TEST_ASSERT_EQUAL_HEX32(0, local_write(master, mod, 0x1006, 0, 10000));

	mark = tb_log_count(&bus);
	tb_advance(&bus, 10000);
	TEST_ASSERT_EQUAL(1, from_slave(0x185, mark));
	TB_ASSERT_LAST(&bus, sp->idx, 0x185, "34 12 56");
	TEST_ASSERT_EQUAL_HEX64(0x1234, val(mod, 0x3000));
	TEST_ASSERT_EQUAL_HEX64(0x56, val(mod, 0x3001));
	TEST_ASSERT_NOT_NULL(tb_last_event(mp, CO_EV_RPDO));
	TEST_ASSERT_EQUAL(1, tb_last_event(mp, CO_EV_RPDO)->u.pdo.nr);

	/* the slave's objects change: the master follows at the next SYNC */
	co_od_set_u16(sod, 0x2000, 0, 0xA55A);
	co_od_set_u8(sod, 0x2001, 0, 0x3C);
	tb_advance(&bus, 5000);
	TEST_ASSERT_EQUAL_HEX64(0x1234, val(mod, 0x3000));
	tb_advance(&bus, 5000);
	TEST_ASSERT_EQUAL_HEX64(0xA55A, val(mod, 0x3000));
	TEST_ASSERT_EQUAL_HEX64(0x3C, val(mod, 0x3001));
	/* one TPDO per SYNC */
	mark = tb_log_count(&bus);
	tb_advance(&bus, 100000);
	TEST_ASSERT_EQUAL(10, from_slave(0x185, mark));
	TEST_ASSERT_EQUAL(0, co_pdo_get_stats(master)->rx_length);
}

static void test_remap_sequence_errors_reach_the_client(void)
{
	/* a valid TPDO 1 first, then the sequence violations */
	const uint32_t map[] = { CO_PDO_MAP(0x2000, 0, 16) };

	remote_map_tpdo(1, 1, 0, 0, 1, map);
	/* entry while valid and sub 0 != 0 */
	sdo_dl(0x1A00, 1, CO_PDO_MAP(0x2001, 0, 8), 4);
	sdo_finish(1, CO_PDO_AB_SEQUENCE);
	/* COB-ID change while valid */
	sdo_dl(0x1800, 1, 0x186, 4);
	sdo_finish(1, SDO_AB_VALUE);
	/* invalidate, clear, then too many bits */
	sdo_dl(0x1800, 1, CO_PDO_COB_INVALID | 0x185, 4);
	sdo_dl(0x1A00, 0, 0, 1);
	sdo_dl(0x1A00, 1, CO_PDO_MAP(0x2002, 0, 32), 4);
	sdo_dl(0x1A00, 2, CO_PDO_MAP(0x2002, 0, 32), 4);
	sdo_dl(0x1A00, 3, CO_PDO_MAP(0x2001, 0, 8), 4);
	sdo_dl(0x1A00, 0, 3, 1);
	sdo_finish(6, SDO_AB_MAP_LEN);
	/* an object the slave does not have */
	sdo_dl(0x1A00, 1, CO_PDO_MAP(0x2999, 0, 8), 4);
	sdo_finish(1, SDO_AB_NO_OBJ);
	TEST_ASSERT_FALSE(co_pdo_is_valid(slave, CO_PDO_TX, 1));
}

static void test_sync_tt3_every_third_sync(void)
{
	const uint32_t map[] = { CO_PDO_MAP(0x2002, 0, 32) };
	size_t mark;

	remote_map_tpdo(2, 3, 0, 0, 1, map);
	start_network();
	TEST_ASSERT_EQUAL_HEX32(0, local_write(master, mod, 0x1006, 0, 10000));
	mark = tb_log_count(&bus);
	tb_advance(&bus, 20000);
	TEST_ASSERT_EQUAL(0, from_slave(0x285, mark));
	TEST_ASSERT_EQUAL_HEX64(0, val(mod, 0x3002));
	tb_advance(&bus, 10000);
	TEST_ASSERT_EQUAL(1, from_slave(0x285, mark));
	TEST_ASSERT_EQUAL_HEX64(0xCAFEF00D, val(mod, 0x3002));
	tb_advance(&bus, 60000); /* 9 SYNCs in all */
	TEST_ASSERT_EQUAL(3, from_slave(0x285, mark));
	TEST_ASSERT_EQUAL(9, co_sync_get_stats(master)->tx);
}

/* Time stamps of the slave's TPDO 3 frames (bus filter). */
static uint64_t t3[64];
static unsigned n3;

static tb_action stamp(void *ctx, const co_frame *f, int from, uint64_t n)
{
	(void)ctx;
	(void)n;
	if (f->id == CO_PDO_TPDO_DEFAULT_COB(3, SLAVE) && from == sp->idx && n3 < 64)
		t3[n3++] = bus.now;
	return TB_DELIVER;
}

static void test_event_driven_tt254_inhibit_and_event_timer(void)
{
	const uint32_t map[] = { CO_PDO_MAP(0x2000, 0, 16) };
	uint64_t t0;

	/* inhibit 10 ms (100 x 100 us), event timer 50 ms */
	remote_map_tpdo(3, 254, 100, 50, 1, map);
	n3 = 0;
	bus.filter = stamp;
	start_network();
	t0 = bus.now;
	/* the event timer sends the first one 50 ms after OPERATIONAL */
	tb_advance(&bus, 50000);
	TEST_ASSERT_EQUAL(1, n3);
	TEST_ASSERT_EQUAL_UINT64(t0 + 50000, t3[0]);
	TEST_ASSERT_EQUAL_HEX64(0x1234, val(mod, 0x3003));

	/* a change storm, one change per ms for 30 ms, starting after the
	 * inhibit time of the timer-driven frame */
	tb_advance(&bus, 20000);
	TEST_ASSERT_EQUAL(1, n3);
	t0 = bus.now;
	for (unsigned i = 0; i < 30; i++) {
		co_od_set_u16(sod, 0x2000, 0, (uint16_t)(0x4000 + i));
		co_pdo_object_changed(slave, 0x2000, 0, bus.now);
		tb_advance(&bus, 1000);
	}
	tb_advance(&bus, 1000);
	/* at +0, +10, +20, +30 ms: never closer than the inhibit time */
	TEST_ASSERT_EQUAL(5, n3);
	for (unsigned i = 1; i < 5; i++)
		TEST_ASSERT_EQUAL_UINT64(t0 + (i - 1) * 10000u, t3[i]);
	/* the master holds the slave's last value */
	TEST_ASSERT_EQUAL_HEX64(val(sod, 0x2000), val(mod, 0x3003));
	TEST_ASSERT_EQUAL_HEX64(0x4000 + 29, val(mod, 0x3003));

	/* then quiet: the event timer repeats every 50 ms after the last */
	tb_advance(&bus, 49000 + 100000);
	TEST_ASSERT_EQUAL(8, n3);
	TEST_ASSERT_EQUAL_UINT64(t3[4] + 50000, t3[5]);
	TEST_ASSERT_EQUAL_UINT64(t3[5] + 50000, t3[6]);
	TEST_ASSERT_EQUAL_UINT64(t3[6] + 50000, t3[7]);
	bus.filter = NULL;

	/* STOPPED: the slave falls silent */
	TEST_ASSERT_EQUAL(0, co_nmt_master_send(master, SLAVE, CO_NMT_CS_STOP, bus.now));
	tb_settle(&bus, 1000);
	{
		size_t mark = tb_log_count(&bus);
		tb_advance(&bus, 500000);
		TEST_ASSERT_EQUAL(0, from_slave(0x385, mark));
	}
}

static void test_master_requests_rtr_tpdo(void)
{
	const uint32_t map[] = { CO_PDO_MAP(0x2002, 0, 32) };

	remote_map_tpdo(2, 253, 0, 0, 1, map);
	start_network();
	TEST_ASSERT_EQUAL(0, co_pdo_rpdo_request(master, 2, bus.now));
	tb_pump(&bus);
	TEST_ASSERT_EQUAL_HEX64(0xCAFEF00D, val(mod, 0x3002));
	TEST_ASSERT_EQUAL(1, co_pdo_get_stats(slave)->rtr);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_remap_over_sdo_then_sync_tt1);
	RUN_TEST(test_remap_sequence_errors_reach_the_client);
	RUN_TEST(test_sync_tt3_every_third_sync);
	RUN_TEST(test_event_driven_tt254_inhibit_and_event_timer);
	RUN_TEST(test_master_requests_rtr_tpdo);
	return UNITY_END();
}
