/* SPDX-License-Identifier: MIT */
/* EMCY producer (1001h, 1003h, 1014h, 1015h) and consumer (1028h)
 * (CiA 301 §7.2.7). */
#include <errno.h>
#include <string.h>

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

static void assert_last_sdo(const uint8_t exp[8])
{
	const co_frame *f = ecf_tx_last(&x, 0x580 + ID);
	TEST_ASSERT_NOT_NULL(f);
	TEST_ASSERT_EQUAL_UINT8(8, f->len);
	TEST_ASSERT_EQUAL_HEX8_ARRAY(exp, f->data, 8);
}

static uint32_t u32(uint16_t idx, uint8_t sub)
{
	uint32_t v = 0xDEADBEEF;
	TEST_ASSERT_EQUAL_INT(0, co_od_get_u32(x.od, idx, sub, &v));
	return v;
}

static uint8_t u8(uint16_t idx, uint8_t sub)
{
	uint8_t v = 0xEE;
	TEST_ASSERT_EQUAL_INT(0, co_od_get_u8(x.od, idx, sub, &v));
	return v;
}

/* 8 bytes on 80h+id with 1001h in byte 2; 1003h newest at sub 1. */
static void test_send_frame_and_history(void)
{
	ecf_boot(&x, ID);
	const uint8_t msef[5] = { '1', '2', '3', '4', '5' };
	TEST_ASSERT_EQUAL_INT(0, co_emcy_send(x.node, 0xFF00, CO_EMCY_REG_MANUF, msef, 0));
	TEST_ASSERT_EQUAL_UINT(1, x.n_tx);
	const uint8_t exp[8] = { 0x00, 0xFF, 0x81, '1', '2', '3', '4', '5' };
	TEST_ASSERT_EQUAL_HEX32(EMCY_COB, x.tx[0].id);
	TEST_ASSERT_EQUAL_UINT8(8, x.tx[0].len);
	TEST_ASSERT_EQUAL_HEX8_ARRAY(exp, x.tx[0].data, 8);
	TEST_ASSERT_EQUAL_HEX8(0x81, u8(0x1001, 0));
	TEST_ASSERT_EQUAL_UINT8(1, u8(0x1003, 0));
	TEST_ASSERT_EQUAL_HEX32(0x3231FF00, u32(0x1003, 1));

	TEST_ASSERT_EQUAL_INT(0, co_emcy_send(x.node, 0x2310, CO_EMCY_REG_CURRENT, NULL, 0));
	TEST_ASSERT_EQUAL_UINT8(2, u8(0x1003, 0));
	TEST_ASSERT_EQUAL_HEX32(0x00002310, u32(0x1003, 1)); /* newest */
	TEST_ASSERT_EQUAL_HEX32(0x3231FF00, u32(0x1003, 2));
	TEST_ASSERT_EQUAL_HEX8(0x83, u8(0x1001, 0));
	TEST_ASSERT_EQUAL_HEX8(0x83, x.tx[1].data[2]);

	/* Full history (8 subs): the oldest falls off, sub 0 stays 8. */
	for (uint16_t c = 0x1001; c <= 0x1008; c++)
		co_emcy_send(x.node, c, 0, NULL, 0);
	TEST_ASSERT_EQUAL_UINT8(8, u8(0x1003, 0));
	TEST_ASSERT_EQUAL_HEX32(0x1008, u32(0x1003, 1));
	TEST_ASSERT_EQUAL_HEX32(0x1001, u32(0x1003, 8));
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_emcy_send(x.node, 0, 0, NULL, 0));
}

/* 1003h:0 over SDO: 0 clears, anything else is refused; reading past the
 * count gives "no data available". */
static void test_history_clear_over_sdo(void)
{
	ecf_boot(&x, ID);
	co_emcy_send(x.node, 0x5000, 0, NULL, 0);
	co_emcy_send(x.node, 0x5001, 0, NULL, 0);
	const uint8_t bad[8] = { 0x2F, 0x03, 0x10, 0x00, 0x01, 0, 0, 0 };
	const uint8_t ab[8] = { 0x80, 0x03, 0x10, 0x00, 0x30, 0x00, 0x09, 0x06 };
	ecf_sdo_req(&x, bad);
	assert_last_sdo(ab);
	TEST_ASSERT_EQUAL_UINT8(2, u8(0x1003, 0));
	const uint8_t clr[8] = { 0x2F, 0x03, 0x10, 0x00, 0x00, 0, 0, 0 };
	const uint8_t ok[8] = { 0x60, 0x03, 0x10, 0x00, 0, 0, 0, 0 };
	ecf_sdo_req(&x, clr);
	assert_last_sdo(ok);
	TEST_ASSERT_EQUAL_UINT8(0, u8(0x1003, 0));
	TEST_ASSERT_EQUAL_HEX32(0, u32(0x1003, 1));
	const uint8_t rd[8] = { 0x40, 0x03, 0x10, 0x01, 0, 0, 0, 0 };
	const uint8_t nodata[8] = { 0x80, 0x03, 0x10, 0x01, 0x24, 0x00, 0x00, 0x08 };
	ecf_sdo_req(&x, rd);
	assert_last_sdo(nodata);
}

/* 1015h = 10 ms, two EMCYs 1 ms apart: the second is delayed. */
static void test_inhibit_delays_second(void)
{
	ecf_boot(&x, ID);
	co_od_set_u16(x.od, 0x1015, 0, 100); /* 100 x 100 us */
	x.now = 1000 * MS;
	co_emcy_send(x.node, 0x3000, CO_EMCY_REG_VOLTAGE, NULL, x.now);
	ecf_advance(&x, 1001 * MS);
	co_emcy_send(x.node, 0x4000, CO_EMCY_REG_TEMP, NULL, x.now);
	TEST_ASSERT_EQUAL_UINT(1, x.n_tx);
	ecf_advance(&x, 1010 * MS - 1);
	TEST_ASSERT_EQUAL_UINT(1, x.n_tx);
	ecf_advance(&x, 1010 * MS);
	TEST_ASSERT_EQUAL_UINT(2, x.n_tx);
	TEST_ASSERT_EQUAL_UINT64(1010 * MS, x.tx_t[1]);
	TEST_ASSERT_EQUAL_HEX8(0x00, x.tx[1].data[0]);
	TEST_ASSERT_EQUAL_HEX8(0x40, x.tx[1].data[1]);
	TEST_ASSERT_EQUAL_UINT64(1, co_emcy_get_stats(x.node)->queued);

	/* Bounded queue: the 9th waiting frame is refused, not dropped
	 * silently; the ones queued all go out, 10 ms apart. */
	for (unsigned i = 0; i < CO_EMCY_QUEUE_LEN; i++)
		TEST_ASSERT_EQUAL_INT(0,
				      co_emcy_send(x.node, (uint16_t)(0x6000 + i), 0, NULL, x.now));
	TEST_ASSERT_EQUAL_INT(-ENOBUFS, co_emcy_send(x.node, 0x6100, 0, NULL, x.now));
	TEST_ASSERT_EQUAL_UINT64(1, co_emcy_get_stats(x.node)->overflow);
	ecf_advance(&x, 1010 * MS + CO_EMCY_QUEUE_LEN * 10 * MS);
	TEST_ASSERT_EQUAL_UINT(2 + CO_EMCY_QUEUE_LEN, x.n_tx);
	TEST_ASSERT_EQUAL_UINT64(1020 * MS, x.tx_t[2]);
	TEST_ASSERT_EQUAL_HEX8(0x07, x.tx[x.n_tx - 1].data[0]);
}

/* Clearing: 1001h follows the active errors; the error reset EMCY goes
 * out only when none remains. */
static void test_clear(void)
{
	ecf_boot(&x, ID);
	co_emcy_send(x.node, 0x3100, CO_EMCY_REG_VOLTAGE, NULL, 0);
	co_emcy_send(x.node, 0x4200, CO_EMCY_REG_TEMP, NULL, 0);
	TEST_ASSERT_EQUAL_HEX8(0x0D, co_emcy_error_register(x.node));
	ecf_clear(&x);
	TEST_ASSERT_EQUAL_INT(0, co_emcy_clear(x.node, 0x3100, 0));
	TEST_ASSERT_EQUAL_UINT(0, x.n_tx);
	TEST_ASSERT_EQUAL_HEX8(0x09, u8(0x1001, 0));
	TEST_ASSERT_EQUAL_INT(-ENOENT, co_emcy_clear(x.node, 0x3100, 0));
	TEST_ASSERT_EQUAL_INT(0, co_emcy_clear(x.node, 0x4200, 0));
	TEST_ASSERT_EQUAL_UINT(1, x.n_tx);
	const uint8_t reset[8] = { 0, 0, 0, 0, 0, 0, 0, 0 };
	TEST_ASSERT_EQUAL_HEX8_ARRAY(reset, x.tx[0].data, 8);
	TEST_ASSERT_EQUAL_HEX8(0x00, u8(0x1001, 0));
	/* History is not touched by clearing. */
	TEST_ASSERT_EQUAL_UINT8(2, u8(0x1003, 0));
}

/* No EMCY in STOPPED; recorded anyway. */
static void test_no_emcy_in_stopped(void)
{
	ecf_boot(&x, ID);
	co_nmt_local_cmd(x.node, CO_NMT_CS_STOP, 0);
	ecf_clear(&x);
	co_emcy_send(x.node, 0x5000, 0, NULL, 0);
	TEST_ASSERT_EQUAL_UINT(0, x.n_tx);
	TEST_ASSERT_EQUAL_UINT64(1, co_emcy_get_stats(x.node)->tx_suppressed);
	TEST_ASSERT_EQUAL_UINT8(1, u8(0x1003, 0));
	TEST_ASSERT_EQUAL_HEX8(0x01, u8(0x1001, 0));
}

/* 1014h rules (CiA 301 §7.5.2.7). */
static void test_1014_cob_id(void)
{
	ecf_boot(&x, ID);
	/* change while valid -> 0x06090030 */
	const uint8_t chg[8] = { 0x23, 0x14, 0x10, 0x00, 0x90, 0x00, 0x00, 0x00 };
	const uint8_t ab[8] = { 0x80, 0x14, 0x10, 0x00, 0x30, 0x00, 0x09, 0x06 };
	ecf_sdo_req(&x, chg);
	assert_last_sdo(ab);
	/* invalidate -> accepted, and then no EMCY is produced */
	const uint8_t inv[8] = { 0x23, 0x14, 0x10, 0x00, 0x85, 0x00, 0x00, 0x80 };
	const uint8_t ok[8] = { 0x60, 0x14, 0x10, 0x00, 0, 0, 0, 0 };
	ecf_sdo_req(&x, inv);
	assert_last_sdo(ok);
	ecf_clear(&x);
	co_emcy_send(x.node, 0x5000, 0, NULL, 0);
	TEST_ASSERT_EQUAL_UINT(0, x.n_tx);
	/* a restricted CAN-ID (701h) is refused */
	const uint8_t rst[8] = { 0x23, 0x14, 0x10, 0x00, 0x01, 0x07, 0x00, 0x00 };
	ecf_sdo_req(&x, rst);
	assert_last_sdo(ab);
	/* now a new valid id is fine and used */
	ecf_sdo_req(&x, chg);
	assert_last_sdo(ok);
	ecf_clear(&x);
	co_emcy_send(x.node, 0x5001, 0, NULL, 0);
	TEST_ASSERT_EQUAL_UINT(1, x.n_tx);
	TEST_ASSERT_EQUAL_HEX32(0x90, x.tx[0].id);
	/* reset comm: back to 80h + id */
	co_nmt_local_cmd(x.node, CO_NMT_CS_RESET_COMM, 0);
	TEST_ASSERT_EQUAL_HEX32(EMCY_COB, u32(0x1014, 0));
}

/* EMCY on a COB-ID in 1028h -> event; other COB-IDs ignored. */
static void test_consumer(void)
{
	ecf_boot(&x, ID);
	const uint8_t d[8] = { 0x10, 0x82, 0x11, 0xA1, 0xA2, 0xA3, 0xA4, 0xA5 };
	ecf_rx(&x, 0x83, 0, 8, d);
	TEST_ASSERT_EQUAL_UINT(1, ecf_ev_count(&x, CO_EV_EMCY_RX));
	const co_ev_emcy *e = &x.ev.ev[ecf_ev_find(&x, 0, CO_EV_EMCY_RX)].u.emcy;
	TEST_ASSERT_EQUAL_UINT8(3, e->node);
	TEST_ASSERT_EQUAL_HEX16(0x8210, e->code);
	TEST_ASSERT_EQUAL_HEX8(0x11, e->reg);
	const uint8_t m[5] = { 0xA1, 0xA2, 0xA3, 0xA4, 0xA5 };
	TEST_ASSERT_EQUAL_HEX8_ARRAY(m, e->msef, 5);
	TEST_ASSERT_EQUAL_HEX32(0x83, e->cob_id);
	/* 1028h has subs 1..4 only: node 10's EMCY is not consumed. */
	ecf_rx(&x, 0x8A, 0, 8, d);
	/* a short frame on a consumed COB-ID: counted, no event */
	ecf_rx(&x, 0x82, 0, 4, d);
	TEST_ASSERT_EQUAL_UINT(1, ecf_ev_count(&x, CO_EV_EMCY_RX));
	TEST_ASSERT_EQUAL_UINT64(1, co_emcy_get_stats(x.node)->rx_invalid);

	/* 1028h:3 invalid over SDO -> node 3 no longer consumed; sub 2 moved
	 * to another COB-ID -> consumed there. */
	const uint8_t w3[8] = { 0x23, 0x28, 0x10, 0x03, 0x83, 0x00, 0x00, 0x80 };
	const uint8_t ok3[8] = { 0x60, 0x28, 0x10, 0x03, 0, 0, 0, 0 };
	ecf_sdo_req(&x, w3);
	assert_last_sdo(ok3);
	ecf_rx(&x, 0x83, 0, 8, d);
	TEST_ASSERT_EQUAL_UINT(1, ecf_ev_count(&x, CO_EV_EMCY_RX));
	co_od_access a = { .origin = CO_OD_ORIGIN_LOCAL };
	uint8_t v[4] = { 0xF0, 0x00, 0x00, 0x00 };
	TEST_ASSERT_EQUAL_HEX32(0, co_od_write(co_od_find(x.od, 0x1028, 2), v, 4, &a));
	ecf_rx(&x, 0x82, 0, 8, d);
	TEST_ASSERT_EQUAL_UINT(1, ecf_ev_count(&x, CO_EV_EMCY_RX));
	ecf_rx(&x, 0xF0, 0, 8, d);
	TEST_ASSERT_EQUAL_UINT(2, ecf_ev_count(&x, CO_EV_EMCY_RX));
	TEST_ASSERT_EQUAL_UINT8(2, x.ev.ev[x.ev.n - 1].u.emcy.node);
	/* reset comm restores the consumer COB-IDs */
	co_nmt_local_cmd(x.node, CO_NMT_CS_RESET_COMM, 0);
	ecf_rx(&x, 0x83, 0, 8, d);
	TEST_ASSERT_EQUAL_UINT(3, ecf_ev_count(&x, CO_EV_EMCY_RX));
}

/* Without the objects: 80h + id, no history, internal register. */
static void test_without_objects(void)
{
	co_od *od = NULL;
	TEST_ASSERT_EQUAL_INT(0, co_od_create(&od, 8));
	ecf_create(&x, ID, od);
	ecf_advance(&x, 0);
	ecf_clear(&x);
	TEST_ASSERT_EQUAL_INT(0, co_emcy_send(x.node, 0x1000, 0, NULL, 0));
	TEST_ASSERT_EQUAL_UINT(1, x.n_tx);
	TEST_ASSERT_EQUAL_HEX32(EMCY_COB, x.tx[0].id);
	TEST_ASSERT_EQUAL_HEX8(0x01, x.tx[0].data[2]);
	TEST_ASSERT_EQUAL_HEX8(0x01, co_emcy_error_register(x.node));
}

static void test_strings(void)
{
	memset(&x, 0, sizeof(x));
	TEST_ASSERT_EQUAL_STRING("life guard or heartbeat error", co_emcy_code_to_string(0x8130));
	TEST_ASSERT_EQUAL_STRING("?", co_emcy_code_to_string(0xFF00));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_send_frame_and_history);
	RUN_TEST(test_history_clear_over_sdo);
	RUN_TEST(test_inhibit_delays_second);
	RUN_TEST(test_clear);
	RUN_TEST(test_no_emcy_in_stopped);
	RUN_TEST(test_1014_cob_id);
	RUN_TEST(test_consumer);
	RUN_TEST(test_without_objects);
	RUN_TEST(test_strings);
	return UNITY_END();
}
