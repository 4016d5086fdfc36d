/* SPDX-License-Identifier: MIT */
/* Node guarding master and life guarding slave (CiA 301
 * §7.2.8.3.2.1, 100Ch/100Dh). */
#include <errno.h>
#include <string.h>

#include "core/emcy.h"
#include "core/guarding.h"
#include "core/heartbeat.h"
#include "core/nmt.h"
#include "tests/unit/support/errctrl_fixture.h"
#include "tests/unit/support/test_bus.h"
#include "unity.h"

#define ID 5
#define GUARD_COB (0x700 + ID)
#define MS 1000u

static ecf x, m; /* x = slave under test, m = master */

void setUp(void)
{
	memset(&m, 0, sizeof(m));
}

void tearDown(void)
{
	ecf_destroy(&x);
	ecf_destroy(&m);
}

static void rtr(ecf *f, uint32_t id)
{
	ecf_rx(f, id, CO_FRAME_RTR, 0, NULL);
}

/* Slave: answers with state | toggle; 0 first, then alternating. */
static void test_slave_answers_with_toggle(void)
{
	ecf_boot(&x, ID);
	rtr(&x, GUARD_COB);
	rtr(&x, GUARD_COB);
	co_nmt_local_cmd(x.node, CO_NMT_CS_START, 0);
	rtr(&x, GUARD_COB);
	TEST_ASSERT_EQUAL_UINT(3, ecf_tx_count(&x, GUARD_COB));
	TEST_ASSERT_EQUAL_UINT8(1, x.tx[0].len);
	TEST_ASSERT_EQUAL_HEX8(0x7F, x.tx[0].data[0]);
	TEST_ASSERT_EQUAL_HEX8(0xFF, x.tx[1].data[0]);
	TEST_ASSERT_EQUAL_HEX8(0x05, x.tx[2].data[0]);
	/* A data frame on our COB-ID is not an RTR: no answer. */
	ecf_rx1(&x, GUARD_COB, 0x00);
	TEST_ASSERT_EQUAL_UINT(3, ecf_tx_count(&x, GUARD_COB));
	/* Reset comm: the toggle starts at 0 again. */
	co_nmt_local_cmd(x.node, CO_NMT_CS_RESET_COMM, 0);
	ecf_clear(&x);
	rtr(&x, GUARD_COB);
	TEST_ASSERT_EQUAL_HEX8(0x7F, x.tx[0].data[0]);
}

/* 100Ch = 100, 100Dh = 3; the RTRs stop -> GUARD_LIFE_LOST after
 * 300 ms, EMCY 8130h, 1029h. */
static void test_slave_life_guarding(void)
{
	ecf_boot(&x, ID);
	co_od_set_u16(x.od, 0x100C, 0, 100);
	co_od_set_u8(x.od, 0x100D, 0, 3);
	co_nmt_local_cmd(x.node, CO_NMT_CS_START, 0);
	/* Not active before the first RTR. */
	ecf_advance(&x, 5000 * MS);
	TEST_ASSERT_FALSE(co_guard_life_active(x.node));
	TEST_ASSERT_EQUAL_UINT(0, ecf_ev_count(&x, CO_EV_GUARD_LIFE_LOST));

	for (unsigned i = 0; i < 5; i++) {
		rtr(&x, GUARD_COB);
		ecf_advance(&x, x.now + 100 * MS);
	}
	TEST_ASSERT_TRUE(co_guard_life_active(x.node));
	/* last RTR at 5400 ms: lost at 5700 ms, not before */
	ecf_clear(&x);
	ecf_advance(&x, 5700 * MS - 1);
	TEST_ASSERT_EQUAL_UINT(0, ecf_ev_count(&x, CO_EV_GUARD_LIFE_LOST));
	ecf_advance(&x, 5700 * MS);
	int e = ecf_ev_find(&x, 0, CO_EV_GUARD_LIFE_LOST);
	TEST_ASSERT_TRUE(e >= 0);
	TEST_ASSERT_EQUAL_UINT64(5700 * MS, x.ev.ev[e].now_us);
	TEST_ASSERT_TRUE(co_guard_life_lost(x.node));
	const uint8_t emcy[8] = { 0x30, 0x81, 0x11, ID, 0, 0, 0, 0 };
	TEST_ASSERT_EQUAL_UINT(1, x.n_tx);
	TEST_ASSERT_EQUAL_HEX32(0x80 + ID, x.tx[0].id);
	TEST_ASSERT_EQUAL_HEX8_ARRAY(emcy, x.tx[0].data, 8);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_PRE_OPERATIONAL, co_nmt_get_state(x.node));

	/* The master comes back: resumed, error reset. */
	ecf_clear(&x);
	rtr(&x, GUARD_COB);
	TEST_ASSERT_EQUAL_UINT(1, ecf_ev_count(&x, CO_EV_GUARD_LIFE_RESUMED));
	TEST_ASSERT_FALSE(co_emcy_is_active(x.node, CO_EMCY_LIFE_GUARD));
	TEST_ASSERT_EQUAL_UINT(2, x.n_tx); /* guard answer + EMCY 0000h */
	TEST_ASSERT_EQUAL_HEX32(0x80 + ID, x.tx[1].id);
	TEST_ASSERT_EQUAL_HEX8(0x00, x.tx[1].data[1]);

	/* 100Dh = 0 stops life guarding at once. */
	co_od_access a = { .origin = CO_OD_ORIGIN_SDO };
	uint8_t zero = 0;
	TEST_ASSERT_EQUAL_HEX32(0, co_od_write(co_od_find(x.od, 0x100D, 0), &zero, 1, &a));
	TEST_ASSERT_FALSE(co_guard_life_active(x.node));
	ecf_advance(&x, x.now + 10000 * MS);
	TEST_ASSERT_EQUAL_UINT(0, ecf_ev_count(&x, CO_EV_GUARD_LIFE_LOST));
}

/* With a heartbeat producer the node does not answer guard RTRs. */
static void test_slave_silent_when_heartbeat(void)
{
	ecf_boot(&x, ID);
	co_hb_producer_set(x.node, 100, 0);
	ecf_clear(&x);
	rtr(&x, GUARD_COB);
	TEST_ASSERT_EQUAL_UINT(0, x.n_tx);
}

/* The first frame node `from` put on the bus; fails if none. */
static const co_frame *first_from(const tb_bus *bus, int from)
{
	for (size_t i = 0; i < tb_log_count(bus); i++)
		if (bus->log_from[i] == from)
			return tb_log_at(bus, i);
	TEST_FAIL_MESSAGE("no frame from that node");
	return NULL;
}

/* Master and slave wired together: steady guarding, no events. */
static void test_master_with_real_slave(void)
{
	tb_bus bus;
	co_node_config mc = { .node_id = 1 }, sc = { .node_id = ID };

	tb_init(&bus);
	bus.now = 0;
	tb_port *pm = tb_add_node(&bus, &mc, ecf_od_std(1));
	tb_port *ps = tb_add_node(&bus, &sc, ecf_od_std(ID));
	TEST_ASSERT_NOT_NULL(pm);
	TEST_ASSERT_NOT_NULL(ps);
	/* Both boot on their own (as ecf_boot does), then are wired. */
	pm->deliver = ps->deliver = false;
	co_node_tick(pm->node, 0);
	co_node_tick(ps->node, 0);
	tb_pump(&bus);
	pm->deliver = ps->deliver = true;
	tb_log_clear(&bus);
	tb_events_clear(pm);
	tb_events_clear(ps);
	co_node *master = pm->node;
	co_od *slave_od = ps->od;

	co_od_set_u16(slave_od, 0x100C, 0, 100);
	co_od_set_u8(slave_od, 0x100D, 0, 3);
	TEST_ASSERT_EQUAL_INT(0, co_guard_master_add(master, ID, 100, 3, 0));
	TEST_ASSERT_TRUE(co_guard_master_has(master, ID));
	tb_advance_to(&bus, 1000 * MS);
	/* RTRs at 0, 100, ..., 1000 ms */
	TEST_ASSERT_EQUAL_UINT(11, tb_count_from_id(&bus, pm->idx, GUARD_COB, 0));
	TEST_ASSERT_TRUE(first_from(&bus, pm->idx)->flags & CO_FRAME_RTR);
	TEST_ASSERT_EQUAL_UINT(11, tb_count_from_id(&bus, ps->idx, GUARD_COB, 0));
	TEST_ASSERT_EQUAL_UINT(0, tb_event_count(pm, CO_EV_GUARD_TOGGLE));
	TEST_ASSERT_EQUAL_UINT(0, tb_event_count(pm, CO_EV_GUARD_FAILED));
	TEST_ASSERT_EQUAL_UINT(0, tb_event_count(ps, CO_EV_GUARD_LIFE_LOST));
	/* The slave's state is reported once (unknown -> pre-op). */
	TEST_ASSERT_EQUAL_UINT(1, tb_event_count(pm, CO_EV_HB_STATE));
	co_nmt_master_send(master, ID, CO_NMT_CS_START, bus.now);
	tb_advance_to(&bus, 1100 * MS);
	TEST_ASSERT_EQUAL_UINT(2, tb_event_count(pm, CO_EV_HB_STATE));
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_OPERATIONAL, pm->ev[pm->n_ev - 1].u.errctrl.state);
	TEST_ASSERT_EQUAL_UINT8(1, pm->ev[pm->n_ev - 1].u.errctrl.guarded);
	/* The guard answers did not look like heartbeats to the consumer. */
	TEST_ASSERT_EQUAL_UINT(0, tb_event_count(pm, CO_EV_HB_STARTED));

	/* The master stops polling: the slave's life guarding fires. */
	co_guard_master_remove(master, ID);
	tb_advance_to(&bus, 1500 * MS);
	TEST_ASSERT_EQUAL_UINT(1, tb_event_count(ps, CO_EV_GUARD_LIFE_LOST));
	tb_fini(&bus);
}

/* 38 master side: repeated toggle -> GUARD_TOGGLE; no answer for
 * life_factor polls -> GUARD_FAILED; answer again -> GUARD_RESUMED. */
static void test_master_toggle_and_failure(void)
{
	ecf_boot(&m, 1);
	TEST_ASSERT_EQUAL_INT(0, co_guard_master_add(m.node, 9, 100, 3, 0));
	TEST_ASSERT_EQUAL_UINT(1, ecf_tx_count(&m, 0x709));
	ecf_rx1(&m, 0x709, 0x7F); /* toggle 0 */
	ecf_advance(&m, 100 * MS);
	ecf_rx1(&m, 0x709, 0xFF); /* toggle 1 */
	ecf_advance(&m, 200 * MS);
	ecf_rx1(&m, 0x709, 0xFF); /* toggle 1 again */
	int e = ecf_ev_find(&m, 0, CO_EV_GUARD_TOGGLE);
	TEST_ASSERT_TRUE(e >= 0);
	TEST_ASSERT_EQUAL_UINT8(9, m.ev.ev[e].u.errctrl.node);
	TEST_ASSERT_EQUAL_UINT(1, ecf_ev_count(&m, CO_EV_GUARD_TOGGLE));
	/* Resynchronised: the next alternation is fine. */
	ecf_advance(&m, 300 * MS);
	ecf_rx1(&m, 0x709, 0x7F);
	TEST_ASSERT_EQUAL_UINT(1, ecf_ev_count(&m, CO_EV_GUARD_TOGGLE));

	/* Silence after the answer at 300 ms: life time 300 ms -> failed at
	 * 600 ms, not before. */
	ecf_advance(&m, 600 * MS - 1);
	TEST_ASSERT_EQUAL_UINT(0, ecf_ev_count(&m, CO_EV_GUARD_FAILED));
	ecf_advance(&m, 600 * MS);
	e = ecf_ev_find(&m, 0, CO_EV_GUARD_FAILED);
	TEST_ASSERT_TRUE(e >= 0);
	TEST_ASSERT_EQUAL_UINT64(600 * MS, m.ev.ev[e].now_us);
	TEST_ASSERT_TRUE(co_guard_master_failed(m.node, 9));
	ecf_advance(&m, 2000 * MS);
	TEST_ASSERT_EQUAL_UINT(1, ecf_ev_count(&m, CO_EV_GUARD_FAILED));
	/* Polling goes on every 100 ms. */
	TEST_ASSERT_EQUAL_UINT(21, ecf_tx_count(&m, 0x709));
	ecf_rx1(&m, 0x709, 0xFF);
	TEST_ASSERT_EQUAL_UINT(1, ecf_ev_count(&m, CO_EV_GUARD_RESUMED));
	TEST_ASSERT_FALSE(co_guard_master_failed(m.node, 9));

	TEST_ASSERT_EQUAL_INT(-EINVAL, co_guard_master_add(m.node, 0, 100, 3, 0));
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_guard_master_add(m.node, 9, 0, 3, 0));
	TEST_ASSERT_EQUAL_INT(0, co_guard_master_remove(m.node, 9));
	TEST_ASSERT_EQUAL_INT(-ENOENT, co_guard_master_remove(m.node, 9));
}

/* A boot-up of a guarded node is still reported as a boot-up. */
static void test_master_bootup_of_guarded_node(void)
{
	ecf_boot(&m, 1);
	co_guard_master_add(m.node, 9, 100, 3, 0);
	ecf_rx1(&m, 0x709, 0xFF);
	ecf_rx1(&m, 0x709, 0x00);
	TEST_ASSERT_EQUAL_UINT(1, ecf_ev_count(&m, CO_EV_BOOTUP));
	/* The rebooted node's first answer has toggle 0: no toggle event. */
	ecf_advance(&m, 100 * MS);
	ecf_rx1(&m, 0x709, 0x7F);
	TEST_ASSERT_EQUAL_UINT(0, ecf_ev_count(&m, CO_EV_GUARD_TOGGLE));
}

/* Heartbeat and life guarding report their losses to core/errctrl.c:
 * EMCY 8130h stays active while either still has one and is reset when
 * the last one ends, whichever ends first. */
static void test_losses_of_both_protocols_share_one_emcy(void)
{
	ecf_boot(&x, ID);
	co_od_set_u16(x.od, 0x100C, 0, 100);
	co_od_set_u8(x.od, 0x100D, 0, 3);
	TEST_ASSERT_EQUAL_INT(0, co_hb_consumer_set(x.node, 7, 500, 0));
	co_nmt_local_cmd(x.node, CO_NMT_CS_START, 0);
	rtr(&x, GUARD_COB);
	ecf_rx1(&x, 0x707, 0x05);
	ecf_advance(&x, 600 * MS);
	TEST_ASSERT_TRUE(co_guard_life_lost(x.node));
	TEST_ASSERT_EQUAL_UINT(1, co_hb_lost_count(x.node));
	TEST_ASSERT_TRUE(co_emcy_is_active(x.node, CO_EMCY_LIFE_GUARD));

	/* Life guarding back, the heartbeat still lost: 8130h stays. */
	ecf_clear(&x);
	rtr(&x, GUARD_COB);
	TEST_ASSERT_EQUAL_UINT(1, ecf_ev_count(&x, CO_EV_GUARD_LIFE_RESUMED));
	TEST_ASSERT_TRUE(co_emcy_is_active(x.node, CO_EMCY_LIFE_GUARD));
	TEST_ASSERT_EQUAL_UINT(1, ecf_tx_count(&x, GUARD_COB));
	TEST_ASSERT_EQUAL_UINT(1, x.n_tx); /* no error reset EMCY yet */

	/* The heartbeat comes back: no loss left, error reset. */
	ecf_clear(&x);
	ecf_rx1(&x, 0x707, 0x05);
	TEST_ASSERT_FALSE(co_emcy_is_active(x.node, CO_EMCY_LIFE_GUARD));
	TEST_ASSERT_EQUAL_UINT(1, x.n_tx);
	TEST_ASSERT_EQUAL_HEX32(0x80 + ID, x.tx[0].id);
	TEST_ASSERT_EQUAL_HEX8(0x00, x.tx[0].data[1]);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_slave_answers_with_toggle);
	RUN_TEST(test_slave_life_guarding);
	RUN_TEST(test_slave_silent_when_heartbeat);
	RUN_TEST(test_master_with_real_slave);
	RUN_TEST(test_master_toggle_and_failure);
	RUN_TEST(test_master_bootup_of_guarded_node);
	RUN_TEST(test_losses_of_both_protocols_share_one_emcy);
	return UNITY_END();
}
