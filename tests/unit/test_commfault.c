/* SPDX-License-Identifier: MIT */
/* Communication faults of the node itself (core/commfault.h): episodes,
 * their CiA 301 EMCYs (8110h, 8120h, 8140h, 8150h) and error resets, the
 * node-ID collision found on 700h + our own node-ID. */
#include <errno.h>
#include <string.h>

#include "core/commfault.h"
#include "core/emcy.h"
#include "core/nmt.h"
#include "tests/unit/support/errctrl_fixture.h"
#include "unity.h"

#define ID 5
#define EMCY_COB (0x80 + ID)
#define MS 1000u

static ecf x;

void setUp(void) {}
void tearDown(void)
{
	ecf_destroy(&x);
}

static void assert_emcy(unsigned nth, uint16_t code, uint8_t reg, uint8_t msef0)
{
	unsigned seen = 0;
	for (unsigned i = 0; i < x.n_tx; i++) {
		if (x.tx[i].id != EMCY_COB)
			continue;
		if (seen++ != nth)
			continue;
		const uint8_t exp[8] = {
			(uint8_t)code, (uint8_t)(code >> 8), reg, msef0, 0, 0, 0, 0
		};
		TEST_ASSERT_EQUAL_UINT8(8, x.tx[i].len);
		TEST_ASSERT_EQUAL_HEX8_ARRAY(exp, x.tx[i].data, 8);
		return;
	}
	TEST_FAIL_MESSAGE("EMCY not sent");
}

static const co_ev_commfault *fault_ev(unsigned nth)
{
	unsigned seen = 0;
	for (unsigned i = 0; i < x.ev.n; i++)
		if (x.ev.ev[i].kind == CO_EV_COMM_FAULT && seen++ == nth)
			return &x.ev.ev[i].u.commfault;
	return NULL;
}

/* `77F#05` for node 127, here 705#05: one heartbeat of another device on
 * our node-ID begins an episode (EMCY 8150h, msef[0] = the state heard,
 * an event); more frames only count; after the quiet time without one
 * the episode ends with the error reset. */
static void test_id_collision_episode(void)
{
	ecf_boot(&x, ID);
	x.now = 1000 * MS;
	ecf_rx1(&x, 0x700 + ID, 0x05);
	TEST_ASSERT_EQUAL_UINT(1, ecf_tx_count(&x, EMCY_COB));
	assert_emcy(0, CO_EMCY_CAN_ID_COLLISION, 0x11, 0x05);
	const co_ev_commfault *e = fault_ev(0);
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_UINT8(CO_COMM_FAULT_ID_COLLISION, e->fault);
	TEST_ASSERT_EQUAL_UINT8(1, e->active);
	TEST_ASSERT_EQUAL_HEX8(0x05, e->info);
	TEST_ASSERT_EQUAL_UINT32(1, e->episodes);

	/* a heartbeat every second keeps it going: no new EMCY, no event */
	for (unsigned s = 2; s <= 6; s++) {
		ecf_advance(&x, s * 1000 * MS);
		ecf_rx1(&x, 0x700 + ID, 0x7F);
	}
	TEST_ASSERT_EQUAL_UINT(1, ecf_tx_count(&x, EMCY_COB));
	TEST_ASSERT_NULL(fault_ev(1));
	const co_commfault_stats *st = co_commfault_get(x.node, CO_COMM_FAULT_ID_COLLISION);
	TEST_ASSERT_TRUE(st->active);
	TEST_ASSERT_EQUAL_UINT32(6, st->occurrences);
	TEST_ASSERT_EQUAL_HEX8(0x7F, st->info);

	/* silent for the quiet time (5 s by default): over, not before */
	ecf_advance(&x, 6000 * MS + CO_COMMFAULT_ID_COLLISION_QUIET_MS * MS - 1);
	TEST_ASSERT_TRUE(st->active);
	ecf_advance(&x, 6000 * MS + CO_COMMFAULT_ID_COLLISION_QUIET_MS * MS);
	TEST_ASSERT_FALSE(st->active);
	TEST_ASSERT_EQUAL_UINT(2, ecf_tx_count(&x, EMCY_COB));
	assert_emcy(1, 0x0000, 0x00, 0);
	e = fault_ev(1);
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_UINT8(0, e->active);

	/* the next frame is a new episode */
	ecf_rx1(&x, 0x700 + ID, 0x00);
	TEST_ASSERT_EQUAL_UINT32(2, st->episodes);
	TEST_ASSERT_EQUAL_UINT(3, ecf_tx_count(&x, EMCY_COB));
	assert_emcy(2, CO_EMCY_CAN_ID_COLLISION, 0x11, 0x00);
}

/* Only an error-control message shows a device: a remote request is
 * someone guarding us, other lengths or bytes are no NMT state. */
static void test_id_collision_needs_an_errctrl_message(void)
{
	ecf_boot(&x, ID);
	ecf_rx(&x, 0x700 + ID, CO_FRAME_RTR, 1, NULL);
	ecf_rx(&x, 0x700 + ID, 0, 2, (const uint8_t[]){ 0x05, 0x00 });
	ecf_rx1(&x, 0x700 + ID, 0x42);
	ecf_rx1(&x, 0x700 + ID + 1, 0x05); /* another node's heartbeat */
	TEST_ASSERT_EQUAL_UINT(0, ecf_tx_count(&x, EMCY_COB));
	TEST_ASSERT_EQUAL_UINT32(0,
				 co_commfault_get(x.node, CO_COMM_FAULT_ID_COLLISION)->occurrences);
	/* bit 7 is the guarding toggle: still a state */
	ecf_rx1(&x, 0x700 + ID, 0x85);
	TEST_ASSERT_EQUAL_UINT(1, ecf_tx_count(&x, EMCY_COB));
}

/* The controller's way up and down: warning (no EMCY), passive (8120h),
 * back to active (error reset). */
static void test_passive_episode(void)
{
	ecf_boot(&x, ID);
	TEST_ASSERT_EQUAL_INT(0, co_commfault_bus_state(x.node, CO_BUS_LEVEL_WARNING, x.now));
	TEST_ASSERT_EQUAL_UINT(0, ecf_tx_count(&x, EMCY_COB));
	TEST_ASSERT_TRUE(co_commfault_get(x.node, CO_COMM_FAULT_WARNING)->active);
	TEST_ASSERT_EQUAL_INT(0, co_commfault_bus_state(x.node, CO_BUS_LEVEL_PASSIVE, x.now));
	TEST_ASSERT_EQUAL_UINT(1, ecf_tx_count(&x, EMCY_COB));
	assert_emcy(0, CO_EMCY_CAN_PASSIVE, 0x11, 0);
	/* passive again: the same episode */
	TEST_ASSERT_EQUAL_INT(0, co_commfault_bus_state(x.node, CO_BUS_LEVEL_PASSIVE, x.now));
	TEST_ASSERT_EQUAL_UINT(1, ecf_tx_count(&x, EMCY_COB));
	TEST_ASSERT_EQUAL_INT(0, co_commfault_bus_state(x.node, CO_BUS_LEVEL_ACTIVE, x.now));
	TEST_ASSERT_EQUAL_UINT(2, ecf_tx_count(&x, EMCY_COB));
	assert_emcy(1, 0x0000, 0x00, 0);
	TEST_ASSERT_FALSE(co_commfault_get(x.node, CO_COMM_FAULT_WARNING)->active);
	TEST_ASSERT_FALSE(co_commfault_get(x.node, CO_COMM_FAULT_PASSIVE)->active);
	/* events: warning on, passive on, passive off, warning off */
	TEST_ASSERT_EQUAL_UINT(4, ecf_ev_count(&x, CO_EV_COMM_FAULT));
	TEST_ASSERT_EQUAL_UINT8(CO_COMM_FAULT_PASSIVE, fault_ev(2)->fault);
	TEST_ASSERT_EQUAL_UINT8(0, fault_ev(2)->active);
}

/* Passive, then bus-off (1029h: pre-operational), then the driver's
 * restart: 8140h recovered, then the passive's end, the error reset. */
static void test_passive_bus_off_recovery(void)
{
	ecf_boot(&x, ID);
	co_nmt_local_cmd(x.node, CO_NMT_CS_START, 0);
	ecf_clear(&x);
	co_commfault_bus_state(x.node, CO_BUS_LEVEL_PASSIVE, x.now);
	co_commfault_bus_state(x.node, CO_BUS_LEVEL_BUS_OFF, x.now);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_PRE_OPERATIONAL, co_nmt_get_state(x.node));
	TEST_ASSERT_EQUAL_UINT(1, ecf_tx_count(&x, EMCY_COB)); /* 8120h only */
	co_commfault_bus_state(x.node, CO_BUS_LEVEL_ACTIVE, x.now);
	TEST_ASSERT_EQUAL_UINT(3, ecf_tx_count(&x, EMCY_COB));
	assert_emcy(1, CO_EMCY_BUS_OFF_RECOVERED, 0x11, 0);
	assert_emcy(2, 0x0000, 0x00, 0);
	TEST_ASSERT_EQUAL_UINT8(0, co_emcy_error_register(x.node));
	TEST_ASSERT_EQUAL_UINT32(1, co_commfault_get(x.node, CO_COMM_FAULT_BUS_OFF)->episodes);
}

/* Lost frames on both sides share 8110h: raised once, reset when both
 * episodes are over. */
static void test_overrun_and_tx_lost_share_8110(void)
{
	ecf_boot(&x, ID);
	TEST_ASSERT_EQUAL_INT(0, co_commfault_set_quiet_ms(x.node, CO_COMM_FAULT_RX_OVERRUN, 100));
	TEST_ASSERT_EQUAL_INT(0, co_commfault_set_quiet_ms(x.node, CO_COMM_FAULT_TX_LOST, 300));
	co_commfault_occurred(x.node, CO_COMM_FAULT_RX_OVERRUN, 12, x.now);
	assert_emcy(0, CO_EMCY_CAN_OVERRUN, 0x11, 1);
	co_commfault_occurred(x.node, CO_COMM_FAULT_TX_LOST, 3, x.now);
	assert_emcy(1, CO_EMCY_CAN_OVERRUN, 0x11, 2);
	ecf_advance(&x, 100 * MS);
	TEST_ASSERT_FALSE(co_commfault_get(x.node, CO_COMM_FAULT_RX_OVERRUN)->active);
	TEST_ASSERT_EQUAL_UINT(2, ecf_tx_count(&x, EMCY_COB)); /* tx still lost */
	ecf_advance(&x, 300 * MS);
	TEST_ASSERT_EQUAL_UINT(3, ecf_tx_count(&x, EMCY_COB));
	assert_emcy(2, 0x0000, 0x00, 0);
	TEST_ASSERT_EQUAL_UINT32(12,
				 co_commfault_get(x.node, CO_COMM_FAULT_RX_OVERRUN)->occurrences);
	co_commfault_reset_counters(x.node);
	TEST_ASSERT_EQUAL_UINT32(0,
				 co_commfault_get(x.node, CO_COMM_FAULT_RX_OVERRUN)->occurrences);
	TEST_ASSERT_EQUAL_UINT32(0, co_commfault_get(x.node, CO_COMM_FAULT_TX_LOST)->episodes);
}

static void test_bad_arguments(void)
{
	ecf_boot(&x, ID);
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_commfault_occurred(x.node, CO_COMM_FAULT_PASSIVE, 1, 0));
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_commfault_occurred(x.node, CO_COMM_FAULT_COUNT, 1, 0));
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_commfault_occurred(x.node, CO_COMM_FAULT_TX_LOST, 0, 0));
	TEST_ASSERT_EQUAL_INT(-EINVAL,
			      co_commfault_set_quiet_ms(x.node, CO_COMM_FAULT_ID_COLLISION, 0));
	TEST_ASSERT_EQUAL_INT(-EINVAL,
			      co_commfault_set_quiet_ms(x.node, CO_COMM_FAULT_BUS_OFF, 10));
	TEST_ASSERT_NULL(co_commfault_get(x.node, CO_COMM_FAULT_COUNT));
	TEST_ASSERT_EQUAL_STRING("id-collision",
				 co_comm_fault_to_string(CO_COMM_FAULT_ID_COLLISION));
	TEST_ASSERT_EQUAL_STRING("tx-lost", co_comm_fault_to_string(CO_COMM_FAULT_TX_LOST));
	TEST_ASSERT_EQUAL_STRING("?", co_comm_fault_to_string(CO_COMM_FAULT_COUNT));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_id_collision_episode);
	RUN_TEST(test_id_collision_needs_an_errctrl_message);
	RUN_TEST(test_passive_episode);
	RUN_TEST(test_passive_bus_off_recovery);
	RUN_TEST(test_overrun_and_tx_lost_share_8110);
	RUN_TEST(test_bad_arguments);
	return UNITY_END();
}
