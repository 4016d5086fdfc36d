/* SPDX-License-Identifier: MIT */
/*
 * SDO server against a scripted client: golden frames of the STI
 * transducer (docs/cosim.md), every abort path, segmented and block
 * protocol details, deferred answers, channel COB-ID rules, timeouts.
 */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "unity.h"

#include "core/co.h"
#include "core/crc16.h"
#include "core/nmt.h"
#include "core/sdo_server.h"
#include "core/store.h"
#include "tests/unit/support/test_bus.h"
#include "tests/unit/support/test_od_fixture.h"

static tb_bus bus;
static tb_port *srv;

static void make_server(co_node_config *cfg)
{
	tb_init(&bus);
	cfg->node_id = cfg->node_id ? cfg->node_id : 1;
	srv = tb_add_node(&bus, cfg, fx_od_new());
	TEST_ASSERT_NOT_NULL(srv);
}

void setUp(void)
{
	co_node_config cfg = { 0 };
	make_server(&cfg);
}

void tearDown(void)
{
	tb_fini(&bus);
}

static void req(const char *hex)
{
	tb_send_hex(&bus, 0x601, hex);
}

#define EXPECT(hex) TB_ASSERT_LAST(&bus, 0, 0x581, hex)

static void expect_abort(uint16_t idx, uint8_t sub, uint32_t code)
{
	char hex[64];

	snprintf(hex, sizeof(hex), "80 %02X %02X %02X %02X %02X %02X %02X", idx & 0xFF, idx >> 8,
		 sub, code & 0xFF, (code >> 8) & 0xFF, (code >> 16) & 0xFF, code >> 24);
	EXPECT(hex);
	const co_event *ev = tb_last_event(srv, CO_EV_SDO_SERVER_DONE);
	TEST_ASSERT_NOT_NULL(ev);
	TEST_ASSERT_EQUAL_HEX32(code, ev->u.sdo_srv.abort);
}

static void send_frame_raw(uint32_t id, const uint8_t d[8])
{
	co_frame f;
	co_frame_init(&f, id, 8);
	memcpy(f.data, d, 8);
	tb_send(&bus, &f);
}

/* ---- golden frames (the STI transducer) ---------------------------------- */

static void test_golden_v1_v2_heartbeat_time(void)
{
	uint16_t v;

	req("2B 17 10 00 A0 0F 00 00");
	EXPECT("60 17 10 00 00 00 00 00");
	TEST_ASSERT_EQUAL(0, co_od_get_u16(srv->od, 0x1017, 0, &v));
	TEST_ASSERT_EQUAL_UINT16(4000, v);
	const co_event *ev = tb_last_event(srv, CO_EV_OD_WRITTEN);
	TEST_ASSERT_NOT_NULL(ev);
	TEST_ASSERT_EQUAL_HEX16(0x1017, ev->u.od.index);
}

static void test_golden_v3_to_v6_real32_write_read(void)
{
	float f;

	req("23 04 20 01 A4 70 9D 3F");
	EXPECT("60 04 20 01 00 00 00 00");
	TEST_ASSERT_EQUAL(0, co_od_get_r32(srv->od, 0x2004, 1, &f));
	TEST_ASSERT_EQUAL_FLOAT(1.23f, f);
	req("40 04 20 01 00 00 00 00");
	EXPECT("43 04 20 01 A4 70 9D 3F");
}

static void test_golden_v7_v8_store_save(void)
{
	TEST_ASSERT_EQUAL(
		0, co_store_attach(srv->node, NULL, NULL, 3, CO_STORE_CAP_CMD, CO_STORE_CAP_CMD));
	req("23 10 10 01 73 61 76 65");
	EXPECT("60 10 10 01 00 00 00 00");
	TEST_ASSERT_EQUAL(1, tb_event_count(srv, CO_EV_STORE));
}

static void test_golden_derived_uploads(void)
{
	req("40 00 10 00 00 00 00 00");
	EXPECT("43 00 10 00 94 01 04 00");
	req("40 18 10 01 00 00 00 00");
	EXPECT("43 18 10 01 50 02 00 00");
	req("40 17 10 00 00 00 00 00");
	EXPECT("4B 17 10 00 E8 03 00 00");
	req("40 01 10 00 00 00 00 00");
	EXPECT("4F 01 10 00 00 00 00 00");
	req("40 18 10 04 00 00 00 00");
	EXPECT("43 18 10 04 40 E2 01 00");
}

static void test_golden_abort_missing_object(void)
{
	req("40 01 20 00 00 00 00 00");
	EXPECT("80 01 20 00 00 00 02 06");
}

/* The sheet's printed frames are wrong; a strict server must say why. */
static void test_printed_v3_with_2B_is_too_short(void)
{
	req("2B 04 20 01 A4 70 9D 3F");
	expect_abort(0x2004, 1, 0x06070013);
}

static void test_printed_v7_reversed_signature_refused(void)
{
	TEST_ASSERT_EQUAL(0, co_store_attach(srv->node, NULL, NULL, 1, 1, 1));
	req("23 10 10 01 65 76 61 73");
	expect_abort(0x1010, 1, 0x08000020);
	TEST_ASSERT_EQUAL(0, tb_event_count(srv, CO_EV_STORE));
}

/* Device sheets print "23 17 10 00 A0 0F 00 00" (4 bytes to the U16 1017h).
 * Strict: too long. Lenient mode accepts it because the surplus is zero. */
static void test_4_bytes_to_u16_strict_and_lenient(void)
{
	req("23 17 10 00 A0 0F 00 00");
	expect_abort(0x1017, 0, 0x06070012);
	tearDown();
	co_node_config cfg = { .sdo_server_lenient_size = true };
	make_server(&cfg);
	req("23 17 10 00 A0 0F 00 00");
	EXPECT("60 17 10 00 00 00 00 00");
	req("23 17 10 00 A0 0F 01 00"); /* non-zero surplus: still refused */
	expect_abort(0x1017, 0, 0x06070012);
}

/* ---- abort paths ------------------------------------------------------------ */

static void test_abort_unknown_index_and_sub(void)
{
	req("40 FF 5F 00 00 00 00 00");
	expect_abort(0x5FFF, 0, 0x06020000);
	req("40 18 10 05 00 00 00 00");
	expect_abort(0x1018, 5, 0x06090011);
	req("40 04 21 02 00 00 00 00"); /* sub-index gap */
	expect_abort(0x2104, 2, 0x06090011);
	req("40 04 21 03 00 00 00 00");
	EXPECT("4F 04 21 03 03 00 00 00");
	req("2F 04 21 02 05 00 00 00");
	expect_abort(0x2104, 2, 0x06090011);
}

static void test_abort_read_only_const_write_only(void)
{
	req("23 00 10 00 00 00 00 00");
	expect_abort(0x1000, 0, 0x06010002);
	req("23 00 23 00 00 00 00 00");
	expect_abort(0x2300, 0, 0x06010002);
	req("40 00 21 00 00 00 00 00");
	expect_abort(0x2100, 0, 0x06010001);
	req("2F 00 21 00 05 00 00 00"); /* write-only accepts writes */
	EXPECT("60 00 21 00 00 00 00 00");
}

static void test_abort_wrong_length(void)
{
	req("23 01 21 00 20 00 00 00"); /* 4 bytes to U16 */
	expect_abort(0x2101, 0, 0x06070012);
	req("2F 01 21 00 20 00 00 00"); /* 1 byte to U16 */
	expect_abort(0x2101, 0, 0x06070013);
	req("21 01 21 00 09 00 00 00"); /* segmented, announces 9 bytes */
	expect_abort(0x2101, 0, 0x06070012);
	req("21 00 10 00 09 00 00 00");
	expect_abort(0x1000, 0, 0x06010002); /* access is checked first */
}

static void test_abort_out_of_range(void)
{
	uint16_t v;

	req("2B 01 21 00 05 00 00 00");
	expect_abort(0x2101, 0, 0x06090032);
	req("2B 01 21 00 E9 03 00 00"); /* 1001 */
	expect_abort(0x2101, 0, 0x06090031);
	TEST_ASSERT_EQUAL(0, co_od_get_u16(srv->od, FX_IDX_LIMITED, 0, &v));
	TEST_ASSERT_EQUAL_UINT16(100, v); /* unchanged */
	req("2B 01 21 00 E8 03 00 00");   /* 1000 is the limit itself */
	EXPECT("60 01 21 00 00 00 00 00");
	req("2B 03 21 00 9B FF 00 00"); /* -101 */
	expect_abort(0x2103, 0, 0x06090032);
	req("2B 03 21 00 9C FF 00 00"); /* -100 */
	EXPECT("60 03 21 00 00 00 00 00");
	req("2F 02 21 00 02 00 00 00"); /* BOOLEAN 2 */
	expect_abort(0x2102, 0, 0x06090030);
}

static void test_abort_invalid_command_specifier(void)
{
	req("E0 00 10 00 00 00 00 00"); /* ccs 7 */
	expect_abort(0x1000, 0, 0x05040001);
	req("60 00 10 00 00 00 00 00"); /* upload segment with no transfer */
	expect_abort(0x1000, 0, 0x05040001);
	req("00 00 00 00 00 00 00 00"); /* download segment with no transfer */
	expect_abort(0x0000, 0, 0x05040001);
	/* A segmented upload in progress: a download segment is wrong. */
	req("40 08 10 00 00 00 00 00");
	req("00 00 00 00 00 00 00 00");
	expect_abort(0x1008, 0, 0x05040001);
}

static void test_abort_toggle_segmented_download(void)
{
	req("21 02 24 00 0A 00 00 00"); /* 10 bytes to 2402h */
	EXPECT("60 02 24 00 00 00 00 00");
	req("00 61 62 63 64 65 66 67");
	EXPECT("20 00 00 00 00 00 00 00");
	req("05 68 69 6A 00 00 00 00"); /* toggle 0 again */
	expect_abort(0x2402, 0, 0x05030000);
	uint8_t buf[64];
	uint32_t len;
	TEST_ASSERT_EQUAL(0, co_od_get_bytes(srv->od, FX_IDX_STR, 0, buf, sizeof(buf), &len));
	TEST_ASSERT_EQUAL_UINT32(2, len); /* still "hi" */
}

static void test_abort_toggle_segmented_upload(void)
{
	req("40 08 10 00 00 00 00 00");
	req("60 00 00 00 00 00 00 00");
	req("60 00 00 00 00 00 00 00"); /* toggle not alternated */
	expect_abort(0x1008, 0, 0x05030000);
}

static void test_segmented_download_more_than_announced(void)
{
	req("21 02 24 00 03 00 00 00");
	req("01 61 62 63 64 65 66 67"); /* 7 bytes, announced 3 */
	expect_abort(0x2402, 0, 0x06070010);
}

static uint32_t refuse_check(void *ctx, co_od_entry *e, const co_od_access *a)
{
	(void)e;
	(void)a;
	return *(uint32_t *)ctx;
}

static int after_calls;
static void count_after(void *ctx, co_od_entry *e, const co_od_access *a)
{
	(void)ctx;
	(void)e;
	(void)a;
	after_calls++;
}

static const co_od_hooks refuse_hooks = { .check_write = refuse_check, .after_write = count_after };

static void test_abort_refused_by_hook_value_unchanged(void)
{
	uint32_t code = 0x08000022, v;

	after_calls = 0;
	TEST_ASSERT_EQUAL(0, co_od_set_hooks(srv->od, FX_IDX_HOOKED, 0, &refuse_hooks, &code));
	req("23 00 24 00 01 02 03 04");
	expect_abort(0x2400, 0, 0x08000022);
	TEST_ASSERT_EQUAL(0, co_od_get_u32(srv->od, FX_IDX_HOOKED, 0, &v));
	TEST_ASSERT_EQUAL_HEX32(7, v);
	TEST_ASSERT_EQUAL(0, after_calls);
	TEST_ASSERT_EQUAL(0, tb_event_count(srv, CO_EV_OD_WRITTEN));
	code = 0;
	req("23 00 24 00 01 02 03 04");
	EXPECT("60 00 24 00 00 00 00 00");
	TEST_ASSERT_EQUAL(0, co_od_get_u32(srv->od, FX_IDX_HOOKED, 0, &v));
	TEST_ASSERT_EQUAL_HEX32(0x04030201, v);
	TEST_ASSERT_EQUAL(1, after_calls);
}

static void test_abort_timeout_per_frame(void)
{
	req("21 02 24 00 0A 00 00 00");
	EXPECT("60 02 24 00 00 00 00 00");
	TEST_ASSERT_TRUE(co_node_next_deadline_us(srv->node) <= bus.now + 1000000);
	tb_advance(&bus, 900000);
	req("00 61 62 63 64 65 66 67"); /* restarts the timeout */
	tb_advance(&bus, 999999);
	EXPECT("20 00 00 00 00 00 00 00");
	tb_advance(&bus, 1);
	expect_abort(0x2402, 0, 0x05040000);
	TEST_ASSERT_FALSE(sdo_server_busy(srv->node, 0));
}

static void test_client_abort_ends_transfer(void)
{
	req("21 02 24 00 0A 00 00 00");
	req("80 02 24 00 00 00 04 05");
	const co_event *ev = tb_last_event(srv, CO_EV_SDO_SERVER_DONE);
	TEST_ASSERT_NOT_NULL(ev);
	TEST_ASSERT_EQUAL_HEX32(0x05040000, ev->u.sdo_srv.abort);
	TEST_ASSERT_FALSE(sdo_server_busy(srv->node, 0));
	size_t n = tb_count_from_id(&bus, 0, 0x581, 0);
	req("80 00 10 00 00 00 00 08"); /* abort in idle: silence */
	TEST_ASSERT_EQUAL(n, tb_count_from_id(&bus, 0, 0x581, 0));
}

static void test_short_and_rtr_frames_ignored(void)
{
	size_t n;

	tb_send_hex(&bus, 0x601, "40 00 10 00");
	co_frame f = tb_frame(0x601, "40 00 10 00 00 00 00 00");
	f.flags = CO_FRAME_RTR;
	tb_send(&bus, &f);
	n = tb_count_from_id(&bus, 0, 0x581, 0);
	TEST_ASSERT_EQUAL(0, n);
}

/* ---- segmented transfers ------------------------------------------------------ */

static void test_segmented_upload_string_1008(void)
{
	/* "STI-SIM pressure transducer", 27 bytes: 3 x 7 + 6. */
	req("40 08 10 00 00 00 00 00");
	EXPECT("41 08 10 00 1B 00 00 00");
	req("60 00 00 00 00 00 00 00");
	EXPECT("00 53 54 49 2D 53 49 4D");
	req("70 00 00 00 00 00 00 00");
	EXPECT("10 20 70 72 65 73 73 75");
	req("60 00 00 00 00 00 00 00");
	EXPECT("00 72 65 20 74 72 61 6E");
	req("70 00 00 00 00 00 00 00");
	EXPECT("13 73 64 75 63 65 72 00"); /* t=1, n=1, c=1 */
	const co_event *ev = tb_last_event(srv, CO_EV_SDO_SERVER_DONE);
	TEST_ASSERT_EQUAL_HEX32(0, ev->u.sdo_srv.abort);
	TEST_ASSERT_EQUAL_UINT32(27, ev->u.sdo_srv.size);
	TEST_ASSERT_EQUAL(SDO_MODE_SEGMENTED, ev->u.sdo_srv.mode);
}

static void test_segmented_download_string_sets_length(void)
{
	char buf[65];
	uint32_t len;

	req("21 02 24 00 0A 00 00 00");
	req("00 68 65 6C 6C 6F 20 77");
	EXPECT("20 00 00 00 00 00 00 00");
	req("19 6F 72 6C 00 00 00 00"); /* t=1, n=4 -> 3 bytes, c */
	EXPECT("30 00 00 00 00 00 00 00");
	TEST_ASSERT_EQUAL(0, co_od_get_bytes(srv->od, FX_IDX_STR, 0, buf, 64, &len));
	buf[len] = 0;
	TEST_ASSERT_EQUAL_STRING("hello worl", buf);
	/* Upload of an empty string: segmented, size 0, one empty segment. */
	req("21 02 24 00 00 00 00 00");
	req("0F 00 00 00 00 00 00 00"); /* n=7, c */
	EXPECT("20 00 00 00 00 00 00 00");
	req("40 02 24 00 00 00 00 00");
	EXPECT("41 02 24 00 00 00 00 00");
	req("60 00 00 00 00 00 00 00");
	EXPECT("0F 00 00 00 00 00 00 00");
}

static void test_expedited_without_size(void)
{
	uint16_t v;

	req("22 17 10 00 34 12 FF FF"); /* e=1, s=0: take the object's size */
	EXPECT("60 17 10 00 00 00 00 00");
	TEST_ASSERT_EQUAL(0, co_od_get_u16(srv->od, 0x1017, 0, &v));
	TEST_ASSERT_EQUAL_HEX16(0x1234, v);
}

/* ---- block transfers, scripted ----------------------------------------------- */

static uint8_t pattern(uint32_t i)
{
	return (uint8_t)(i * 7u + (i >> 8));
}

/* Send bytes [off, off + n * 7) as segments 1..n of a sub-block, skipping
 * segment `skip` and sending `dup` twice (0 = none). */
static void send_segments(uint32_t total, uint32_t off, unsigned n, unsigned skip, unsigned dup)
{
	for (unsigned s = 1; s <= n; s++) {
		uint8_t d[8] = { 0 };
		uint32_t o = off + (s - 1) * 7;
		bool last = o + 7 >= total;
		for (unsigned k = 0; k < 7 && o + k < total; k++)
			d[1 + k] = pattern(o + k);
		d[0] = (uint8_t)(s | (last ? 0x80 : 0));
		if (s != skip)
			send_frame_raw(0x601, d);
		if (s == dup)
			send_frame_raw(0x601, d);
		if (last)
			break;
	}
}

static uint16_t pattern_crc(uint32_t n)
{
	uint16_t crc = 0;
	for (uint32_t i = 0; i < n; i++) {
		uint8_t b = pattern(i);
		crc = crc16_ccitt(crc, &b, 1);
	}
	return crc;
}

static void end_frame(uint32_t total, uint16_t crc)
{
	uint32_t rem = total % 7;
	uint32_t n = rem ? 7 - rem : 0;
	uint8_t d[8] = { (uint8_t)(0xC1 | (n << 2)), (uint8_t)crc, (uint8_t)(crc >> 8) };
	send_frame_raw(0x601, d);
}

static void check_domain(uint32_t total)
{
	co_od_entry *e = co_od_find(srv->od, FX_IDX_DOMAIN, 0);
	TEST_ASSERT_EQUAL_UINT32(total, e->size);
	for (uint32_t i = 0; i < total; i++)
		if (e->data[i] != pattern(i))
			TEST_FAIL_MESSAGE("domain content differs");
}

static void test_block_download_1k_crc_scripted(void)
{
	req("C6 00 22 00 00 04 00 00");
	EXPECT("A4 00 22 00 7F 00 00 00");
	send_segments(1024, 0, 127, 0, 0);
	EXPECT("A2 7F 7F 00 00 00 00 00");
	send_segments(1024, 127 * 7, 127, 0, 0); /* 20 segments, last c */
	EXPECT("A2 14 7F 00 00 00 00 00");
	end_frame(1024, pattern_crc(1024));
	EXPECT("A1 00 00 00 00 00 00 00");
	check_domain(1024);
	const co_event *ev = tb_last_event(srv, CO_EV_SDO_SERVER_DONE);
	TEST_ASSERT_EQUAL(SDO_MODE_BLOCK, ev->u.sdo_srv.mode);
	TEST_ASSERT_EQUAL_UINT32(1024, ev->u.sdo_srv.size);
}

static void test_block_download_lost_and_repeated_segment(void)
{
	req("C6 00 22 00 00 04 00 00");
	send_segments(1024, 0, 127, 5, 9); /* 5 lost, 9 twice */
	EXPECT("A2 04 7F 00 00 00 00 00"); /* last good: 4 */
	/* The client resends from segment 5, numbering from 1 again. */
	send_segments(1024, 4 * 7, 127, 0, 3);
	EXPECT("A2 7F 7F 00 00 00 00 00");
	send_segments(1024, (4 + 127) * 7, 127, 0, 0);
	EXPECT("A2 10 7F 00 00 00 00 00"); /* 1024 - 917 = 107 -> 16 segments */
	end_frame(1024, pattern_crc(1024));
	EXPECT("A1 00 00 00 00 00 00 00");
	check_domain(1024);
}

static void test_block_download_bad_crc(void)
{
	req("C6 00 22 00 00 04 00 00");
	send_segments(1024, 0, 127, 0, 0);
	send_segments(1024, 127 * 7, 127, 0, 0);
	end_frame(1024, (uint16_t)(pattern_crc(1024) ^ 1));
	expect_abort(0x2200, 0, 0x05040004);
}

static void test_block_download_bad_sequence_number(void)
{
	uint8_t d[8] = { 0x00 }; /* seqno 0 */

	req("C6 00 22 00 00 04 00 00");
	send_frame_raw(0x601, d);
	expect_abort(0x2200, 0, 0x05040003);
	req("C6 00 22 00 00 04 00 00");
	d[0] = 0x7F;
	tearDown();
	co_node_config cfg = { .sdo_server_blksize = 10 };
	make_server(&cfg);
	req("C6 00 22 00 00 04 00 00");
	EXPECT("A4 00 22 00 0A 00 00 00");
	d[0] = 11; /* beyond the block size we offered */
	send_frame_raw(0x601, d);
	expect_abort(0x2200, 0, 0x05040003);
}

static void test_block_download_too_big_for_object(void)
{
	req("C6 01 22 00 E9 03 00 00"); /* 1001 bytes to a 1000-byte octet string */
	expect_abort(0x2201, 0, 0x06070012);
}

static void test_block_upload_scripted_with_pst_and_crc(void)
{
	/* 27-byte string, pst 30 -> the server switches to a normal upload. */
	req("A4 08 10 00 7F 1E 00 00");
	EXPECT("41 08 10 00 1B 00 00 00");
	req("80 08 10 00 00 00 00 00");
	/* pst 0: block. */
	req("A4 08 10 00 7F 00 00 00");
	EXPECT("C6 08 10 00 1B 00 00 00");
	req("A3 00 00 00 00 00 00 00");
	EXPECT("84 73 64 75 63 65 72 00"); /* 4th segment "sducer", c */
	size_t mark = tb_log_count(&bus);
	req("A2 02 7F 00 00 00 00 00"); /* only 2 arrived: resend from 3 */
	TEST_ASSERT_EQUAL(2, tb_count_from_id(&bus, 0, 0x581, mark));
	TEST_ASSERT_TRUE(tb_frame_is(tb_log_at(&bus, mark + 1), 0x581, "01 72 65 20 74 72 61 6E"));
	EXPECT("82 73 64 75 63 65 72 00"); /* now numbered 2 */
	req("A2 02 7F 00 00 00 00 00");
	const char *name = FX_DEVICE_NAME;
	uint16_t crc = crc16_ccitt(0, name, 27);
	char hex[64];
	snprintf(hex, sizeof(hex), "C5 %02X %02X 00 00 00 00 00", crc & 0xFF, crc >> 8);
	EXPECT(hex); /* n = 1 */
	req("A1 00 00 00 00 00 00 00");
	const co_event *ev = tb_last_event(srv, CO_EV_SDO_SERVER_DONE);
	TEST_ASSERT_EQUAL_HEX32(0, ev->u.sdo_srv.abort);
	TEST_ASSERT_EQUAL(SDO_MODE_BLOCK, ev->u.sdo_srv.mode);
}

static void test_block_upload_bad_blksize_and_ack(void)
{
	req("A4 08 10 00 00 00 00 00");
	expect_abort(0x1008, 0, 0x05040002);
	req("A4 08 10 00 80 00 00 00");
	expect_abort(0x1008, 0, 0x05040002);
	req("A4 08 10 00 7F 00 00 00");
	req("A3 00 00 00 00 00 00 00");
	req("A2 09 7F 00 00 00 00 00"); /* acks more than were sent */
	expect_abort(0x1008, 0, 0x05040003);
}

static void test_block_refused_when_disabled(void)
{
	tearDown();
	co_node_config cfg = { .sdo_server_no_block = true };
	make_server(&cfg);
	req("C6 00 22 00 00 04 00 00");
	expect_abort(0x2200, 0, 0x05040001);
	req("A4 08 10 00 7F 00 00 00");
	expect_abort(0x1008, 0, 0x05040001);
}

/* ---- deferred answers ------------------------------------------------------ */

static int reads;
static uint32_t defer_read(void *ctx, co_od_entry *e, const co_od_access *a)
{
	(void)ctx;
	(void)e;
	TEST_ASSERT_EQUAL(CO_OD_ORIGIN_SDO, a->origin);
	reads++;
	return CO_OD_DEFERRED;
}

static uint32_t defer_write(void *ctx, co_od_entry *e, const co_od_access *a)
{
	(void)ctx;
	(void)e;
	TEST_ASSERT_NOT_NULL(a->data);
	return CO_OD_DEFERRED;
}

static const co_od_hooks defer_hooks = { .check_write = defer_write, .read = defer_read };

static void test_deferred_read_answers_after_continue(void)
{
	static const uint8_t data[] = { 0xAA, 0xBB, 0xCC, 0xDD, 0xEE, 0xFF, 0x11, 0x22, 0x33 };

	reads = 0;
	co_od_set_hooks(srv->od, FX_IDX_HOOKED, 0, &defer_hooks, NULL);
	size_t n = tb_count_from_id(&bus, 0, 0x581, 0);
	req("40 00 24 00 00 00 00 00");
	TEST_ASSERT_EQUAL(1, reads);
	tb_advance(&bus, 200000);
	TEST_ASSERT_EQUAL(n, tb_count_from_id(&bus, 0, 0x581, 0)); /* nothing yet */
	TEST_ASSERT_TRUE(sdo_server_busy(srv->node, 0));
	/* Continue with the entry's own (refreshed) value. */
	co_od_set_u32(srv->od, FX_IDX_HOOKED, 0, 0x12345678);
	TEST_ASSERT_EQUAL(0, sdo_server_continue(srv->node, 0, 0, NULL, 0, bus.now));
	tb_pump(&bus);
	EXPECT("43 00 24 00 78 56 34 12");
	/* Continue with foreign data (a gateway relaying a remote value). */
	req("40 00 24 00 00 00 00 00");
	TEST_ASSERT_EQUAL(0, sdo_server_continue(srv->node, 0, 0, data, sizeof(data), bus.now));
	tb_pump(&bus);
	EXPECT("41 00 24 00 09 00 00 00");
	req("60 00 00 00 00 00 00 00");
	EXPECT("00 AA BB CC DD EE FF 11");
	req("70 00 00 00 00 00 00 00");
	EXPECT("1B 22 33 00 00 00 00 00");
	/* Continue with an abort. */
	req("40 00 24 00 00 00 00 00");
	TEST_ASSERT_EQUAL(0, sdo_server_continue(srv->node, 0, 0x06060000, NULL, 0, bus.now));
	tb_pump(&bus);
	expect_abort(0x2400, 0, 0x06060000);
	TEST_ASSERT_EQUAL(-ENOENT, sdo_server_continue(srv->node, 0, 0, NULL, 0, bus.now));
}

static void test_deferred_read_still_times_out(void)
{
	co_od_set_hooks(srv->od, FX_IDX_HOOKED, 0, &defer_hooks, NULL);
	req("40 00 24 00 00 00 00 00");
	tb_advance(&bus, 1000000);
	expect_abort(0x2400, 0, 0x05040000);
	TEST_ASSERT_EQUAL(-ENOENT, sdo_server_continue(srv->node, 0, 0, NULL, 0, bus.now));
}

static void test_deferred_write_commit_and_refuse(void)
{
	uint32_t v;

	co_od_set_hooks(srv->od, FX_IDX_HOOKED, 0, &defer_hooks, NULL);
	req("23 00 24 00 01 00 00 00");
	TEST_ASSERT_EQUAL(0, co_od_get_u32(srv->od, FX_IDX_HOOKED, 0, &v));
	TEST_ASSERT_EQUAL_UINT32(7, v); /* not yet */
	TEST_ASSERT_EQUAL(0, sdo_server_continue(srv->node, 0, 0, NULL, 0, bus.now));
	tb_pump(&bus);
	EXPECT("60 00 24 00 00 00 00 00");
	TEST_ASSERT_EQUAL(0, co_od_get_u32(srv->od, FX_IDX_HOOKED, 0, &v));
	TEST_ASSERT_EQUAL_UINT32(1, v);
	req("23 00 24 00 02 00 00 00");
	TEST_ASSERT_EQUAL(0, sdo_server_continue(srv->node, 0, 0x08000021, NULL, 0, bus.now));
	tb_pump(&bus);
	expect_abort(0x2400, 0, 0x08000021);
	TEST_ASSERT_EQUAL(0, co_od_get_u32(srv->od, FX_IDX_HOOKED, 0, &v));
	TEST_ASSERT_EQUAL_UINT32(1, v);
	/* A client abort while deferred: the continue finds nothing. */
	req("23 00 24 00 03 00 00 00");
	req("80 00 24 00 00 00 00 08");
	TEST_ASSERT_EQUAL(-ENOENT, sdo_server_continue(srv->node, 0, 0, NULL, 0, bus.now));
	TEST_ASSERT_EQUAL(0, co_od_get_u32(srv->od, FX_IDX_HOOKED, 0, &v));
	TEST_ASSERT_EQUAL_UINT32(1, v);
}

static uint32_t in_place_size;
static uint32_t defer_in_place(void *ctx, co_od_entry *e, const co_od_access *a)
{
	(void)ctx;
	(void)e;
	TEST_ASSERT_NULL(a->data); /* streamed in place: only the size is known */
	in_place_size = a->size;
	return CO_OD_DEFERRED;
}

static const co_od_hooks defer_in_place_hooks = { .check_write = defer_in_place };

/* An in-place (large) entry whose check hook defers at initiate: the
 * initiate confirmation waits for the continue. */
static void test_deferred_check_at_initiate_for_in_place_domain(void)
{
	co_od_set_hooks(srv->od, FX_IDX_DOMAIN, 0, &defer_in_place_hooks, NULL);
	size_t n = tb_count_from_id(&bus, 0, 0x581, 0);
	req("21 00 22 00 0A 00 00 00");
	TEST_ASSERT_EQUAL(n, tb_count_from_id(&bus, 0, 0x581, 0));
	TEST_ASSERT_EQUAL_UINT32(10, in_place_size);
	TEST_ASSERT_EQUAL(0, sdo_server_continue(srv->node, 0, 0, NULL, 0, bus.now));
	tb_pump(&bus);
	EXPECT("60 00 22 00 00 00 00 00");
	req("00 30 31 32 33 34 35 36");
	req("19 37 38 39 00 00 00 00");
	EXPECT("30 00 00 00 00 00 00 00");
	TEST_ASSERT_EQUAL_MEMORY("0123456789", co_od_find(srv->od, FX_IDX_DOMAIN, 0)->data, 10);
	TEST_ASSERT_EQUAL(-EINVAL, sdo_server_continue(srv->node, 9, 0, NULL, 0, bus.now));
}

static uint32_t streamed_size;
static uint8_t streamed_first;
static uint32_t defer_streamed(void *ctx, co_od_entry *e, const co_od_access *a)
{
	(void)ctx;
	TEST_ASSERT_EQUAL_PTR(e->data, a->data); /* all of it, in place */
	streamed_size = a->size;
	streamed_first = a->data[0];
	return CO_OD_DEFERRED;
}

static const co_od_hooks defer_streamed_hooks = { .check_streamed = defer_streamed };

/* An in-place download checked at its end: the last confirmation waits
 * for the continue, and a refusal is the hook's abort code with no
 * CO_EV_OD_WRITTEN (segmented and block). */
static void test_deferred_check_at_end_of_streamed_download(void)
{
	co_od_set_hooks(srv->od, FX_IDX_DOMAIN, 0, &defer_streamed_hooks, NULL);
	streamed_size = 0;
	req("21 00 22 00 0A 00 00 00");
	EXPECT("60 00 22 00 00 00 00 00"); /* no check at initiate */
	req("00 30 31 32 33 34 35 36");
	EXPECT("20 00 00 00 00 00 00 00");
	size_t n = tb_count_from_id(&bus, 0, 0x581, 0);
	req("19 37 38 39 00 00 00 00");
	TEST_ASSERT_EQUAL(n, tb_count_from_id(&bus, 0, 0x581, 0)); /* parked */
	TEST_ASSERT_EQUAL_UINT32(10, streamed_size);
	TEST_ASSERT_EQUAL_HEX8(0x30, streamed_first);
	TEST_ASSERT_EQUAL(0, sdo_server_continue(srv->node, 0, 0, NULL, 0, bus.now));
	tb_pump(&bus);
	EXPECT("30 00 00 00 00 00 00 00");
	TEST_ASSERT_EQUAL_UINT32(10, co_od_find(srv->od, FX_IDX_DOMAIN, 0)->size);
	/* refused at the end of a block download */
	req("C2 00 22 00 03 00 00 00");
	EXPECT("A0 00 22 00 7F 00 00 00");
	req("81 41 42 43 00 00 00 00");
	EXPECT("A2 01 7F 00 00 00 00 00");
	req("D1 00 00 00 00 00 00 00"); /* end: 4 bytes of the last segment unused */
	TEST_ASSERT_EQUAL_UINT32(3, streamed_size);
	TEST_ASSERT_EQUAL(0, sdo_server_continue(srv->node, 0, 0x08000020, NULL, 0, bus.now));
	tb_pump(&bus);
	expect_abort(0x2200, 0, 0x08000020);
	TEST_ASSERT_EQUAL_UINT32(10, co_od_find(srv->od, FX_IDX_DOMAIN, 0)->size);
}

/* A value the application changes while its upload runs goes out as it
 * was at the request: segments and the block end's CRC agree with one
 * value, never a mix of two. */
static void test_upload_sends_the_value_as_it_was_at_the_request(void)
{
	co_od_set_u64(srv->od, FX_IDX_U64, 0, 0x1122334455667788ull);
	req("40 01 24 00 00 00 00 00");
	EXPECT("41 01 24 00 08 00 00 00");
	co_od_set_u64(srv->od, FX_IDX_U64, 0, 0xAAAAAAAAAAAAAAAAull);
	req("60 00 00 00 00 00 00 00");
	EXPECT("00 88 77 66 55 44 33 22");
	req("70 00 00 00 00 00 00 00");
	EXPECT("1D 11 00 00 00 00 00 00");
	/* block upload with CRC: the value changes after the sub-block went */
	co_od_set_u64(srv->od, FX_IDX_U64, 0, 0x1122334455667788ull);
	req("A4 01 24 00 7F 00 00 00");
	EXPECT("C6 01 24 00 08 00 00 00");
	req("A3 00 00 00 00 00 00 00");
	EXPECT("82 11 00 00 00 00 00 00"); /* the sub-block's last segment */
	co_od_set_u64(srv->od, FX_IDX_U64, 0, 0xAAAAAAAAAAAAAAAAull);
	req("A2 02 7F 00 00 00 00 00");
	static const uint8_t v[8] = { 0x88, 0x77, 0x66, 0x55, 0x44, 0x33, 0x22, 0x11 };
	uint16_t crc = crc16_ccitt(0, v, sizeof v);
	char end[40];
	snprintf(end, sizeof end, "D9 %02X %02X 00 00 00 00 00", crc & 0xFF, crc >> 8);
	EXPECT(end);
	req("A1 00 00 00 00 00 00 00");
}

/* Garbage from the bus never crashes the server or leaves it stuck. */
static void test_random_frames_fuzz(void)
{
	static const uint8_t cs[] = { 0x00, 0x10, 0x20, 0x21, 0x23, 0x2B, 0x40, 0x60, 0x70,
				      0x80, 0xA0, 0xA3, 0xA4, 0xC0, 0xC6, 0xC1, 0x01, 0x81 };
	static const uint16_t idx[] = { 0x1008, 0x2200, 0x2201, 0x2402, 0x1017, 0x1000, 0x2400 };
	uint32_t seed = 0xC0FFEE;

	bus.log_on = false;
	for (int i = 0; i < 200000; i++) {
		uint8_t d[8];
		seed = seed * 1664525u + 1013904223u;
		for (int k = 0; k < 8; k++)
			d[k] = (uint8_t)(seed >> (k * 3));
		if (seed & 0x100) {
			d[0] = cs[(seed >> 9) % sizeof(cs)] | (uint8_t)((seed >> 20) & 0x0C);
			co_put_le16(&d[1], idx[(seed >> 13) % 7]);
			d[3] = 0;
		}
		if ((seed & 0xF000) == 0x1000)
			tb_advance(&bus, 1500000);
		send_frame_raw(0x601, d);
	}
	tb_advance(&bus, 2000000);
	TEST_ASSERT_FALSE(sdo_server_busy(srv->node, 0));
	bus.log_on = true;
	req("40 00 10 00 00 00 00 00");
	EXPECT("43 00 10 00 94 01 04 00");
}

/* ---- channels and COB-IDs ------------------------------------------------------ */

static void test_second_channel_cob_id_rules(void)
{
	tearDown();
	co_node_config cfg = { .sdo_server_count = 2 };
	make_server(&cfg);
	uint32_t v;
	TEST_ASSERT_EQUAL(2, sdo_server_channel_count(srv->node));
	TEST_ASSERT_EQUAL(0, co_od_get_u32(srv->od, 0x1201, 1, &v));
	TEST_ASSERT_EQUAL_HEX32(0x80000000, v); /* created invalid */

	req("23 01 12 01 77 00 00 00"); /* invalid -> valid: allowed */
	EXPECT("60 01 12 01 00 00 00 00");
	req("23 01 12 02 F7 05 00 00");
	EXPECT("60 01 12 02 00 00 00 00");
	tb_send_hex(&bus, 0x77, "40 00 10 00 00 00 00 00");
	TB_ASSERT_LAST(&bus, 0, 0x5F7, "43 00 10 00 94 01 04 00");

	req("23 01 12 01 78 00 00 00"); /* valid -> other valid: refused */
	expect_abort(0x1201, 1, 0x06090030);
	req("23 01 12 01 77 00 00 80"); /* set bit 31 first */
	EXPECT("60 01 12 01 00 00 00 00");
	size_t n = tb_count_from_id(&bus, 0, 0x5F7, 0);
	tb_send_hex(&bus, 0x77, "40 00 10 00 00 00 00 00");
	TEST_ASSERT_EQUAL(n, tb_count_from_id(&bus, 0, 0x5F7, 0)); /* channel off */
	req("23 01 12 01 78 00 00 00");
	EXPECT("60 01 12 01 00 00 00 00");
	tb_send_hex(&bus, 0x78, "40 00 10 00 00 00 00 00");
	TB_ASSERT_LAST(&bus, 0, 0x5F7, "43 00 10 00 94 01 04 00");
	req("23 01 12 01 00 08 00 00"); /* bits above 11-bit without bit 29 */
	expect_abort(0x1201, 1, 0x06090030);

	/* Reset communication: back to the predefined (invalid) set. */
	co_node_reset_comm(srv->node, bus.now);
	n = tb_count_from_id(&bus, 0, 0x5F7, 0);
	tb_send_hex(&bus, 0x78, "40 00 10 00 00 00 00 00");
	TEST_ASSERT_EQUAL(n, tb_count_from_id(&bus, 0, 0x5F7, 0));
	req("40 00 10 00 00 00 00 00");
	EXPECT("43 00 10 00 94 01 04 00");
}

static void test_two_channels_in_parallel(void)
{
	tearDown();
	co_node_config cfg = { .sdo_server_count = 2 };
	make_server(&cfg);
	req("23 01 12 01 77 00 00 00");
	req("23 01 12 02 F7 05 00 00");
	/* Segmented uploads of 1008h interleaved on both channels. */
	req("40 08 10 00 00 00 00 00");
	tb_send_hex(&bus, 0x77, "40 08 10 00 00 00 00 00");
	TB_ASSERT_LAST(&bus, 0, 0x5F7, "41 08 10 00 1B 00 00 00");
	req("60 00 00 00 00 00 00 00");
	EXPECT("00 53 54 49 2D 53 49 4D");
	tb_send_hex(&bus, 0x77, "60 00 00 00 00 00 00 00");
	TB_ASSERT_LAST(&bus, 0, 0x5F7, "00 53 54 49 2D 53 49 4D");
	TEST_ASSERT_TRUE(sdo_server_busy(srv->node, 0));
	TEST_ASSERT_TRUE(sdo_server_busy(srv->node, 1));
}

/* ---- CiA 302-7 routing hook ---------------------------------------------- */

static struct {
	unsigned ind, frames, ended;
	uint8_t ch, last[8];
	uint32_t answer;   /* what indication returns */
	bool end_inside;   /* end the route from inside indication */
	bool end_on_frame; /* frame: end the route first and leave the frame */
} rt;

static uint32_t rt_indication(void *ctx, uint8_t ch, const uint8_t d[8], uint64_t now_us)
{
	(void)ctx;
	(void)now_us;
	rt.ind++;
	rt.ch = ch;
	memcpy(rt.last, d, 8);
	if (rt.end_inside) {
		uint8_t refuse[8] = { 0x80, d[1], d[2], d[3], 0x01, 0, 0, 0x0A };
		TEST_ASSERT_EQUAL(0, sdo_server_route_send(srv->node, ch, refuse));
		TEST_ASSERT_EQUAL(0, sdo_server_route_end(srv->node, ch));
	}
	return rt.answer;
}

static bool rt_frame(void *ctx, uint8_t ch, const uint8_t d[8], uint64_t now_us)
{
	(void)ctx;
	(void)now_us;
	rt.frames++;
	rt.ch = ch;
	memcpy(rt.last, d, 8);
	if (rt.end_on_frame) {
		TEST_ASSERT_EQUAL(0, sdo_server_route_end(srv->node, ch));
		return false;
	}
	return true;
}

static void rt_ended(void *ctx, uint8_t ch)
{
	(void)ctx;
	rt.ended++;
	rt.ch = ch;
}

static const sdo_server_route_ops rt_ops = { rt_indication, rt_frame, rt_ended };

static void test_network_indication_without_hook_is_refused(void)
{
	req("E0 02 00 05 00 00 00 00");
	EXPECT("80 02 00 05 01 00 04 05");
}

static void test_routing_hook_owns_the_channel_until_released(void)
{
	uint8_t confirm[8] = { 0xE0, 0x02, 0x00, 0x05, 0, 0, 0, 0 };
	size_t done_before = tb_event_count(srv, CO_EV_SDO_SERVER_DONE);

	memset(&rt, 0, sizeof(rt));
	TEST_ASSERT_EQUAL(0, sdo_server_route_attach(srv->node, &rt_ops, NULL));
	TEST_ASSERT_EQUAL(-ENOENT, sdo_server_route_send(srv->node, 0, confirm));
	req("E0 02 00 05 00 00 00 00");
	TEST_ASSERT_EQUAL(1, rt.ind);
	TEST_ASSERT_TRUE(sdo_server_busy(srv->node, 0));
	TEST_ASSERT_EQUAL(0, sdo_server_route_send(srv->node, 0, confirm));
	EXPECT("E0 02 00 05 00 00 00 00");
	/* every frame, aborts included, goes to the hook; no answer, no timeout */
	req("40 00 10 00 00 00 00 00");
	req("80 00 10 00 00 00 04 05");
	TEST_ASSERT_EQUAL(2, rt.frames);
	TEST_ASSERT_EQUAL_HEX8(0x80, rt.last[0]);
	tb_advance(&bus, 5000000);
	TEST_ASSERT_EQUAL(1, tb_count_from_id(&bus, 0, 0x581, 0));
	TEST_ASSERT_EQUAL(-EBUSY, sdo_server_route_attach(srv->node, NULL, NULL));
	TEST_ASSERT_EQUAL(0, sdo_server_route_end(srv->node, 0));
	TEST_ASSERT_FALSE(sdo_server_busy(srv->node, 0));
	TEST_ASSERT_EQUAL(-ENOENT, sdo_server_route_end(srv->node, 0));
	/* a normal transfer again */
	req("40 00 10 00 00 00 00 00");
	EXPECT("43 00 10 00 94 01 04 00");
	TEST_ASSERT_EQUAL(2, rt.frames);
	TEST_ASSERT_EQUAL(done_before + 1, tb_event_count(srv, CO_EV_SDO_SERVER_DONE));
}

/* The hook learns on a frame that its transfer had ended (the answer to
 * the requester left from elsewhere, and the requester goes on already):
 * it ends the route and leaves the frame, which the server then handles
 * as the new request it is - here a new network indication. */
static void test_frame_left_by_an_ended_route_is_a_new_request(void)
{
	memset(&rt, 0, sizeof(rt));
	TEST_ASSERT_EQUAL(0, sdo_server_route_attach(srv->node, &rt_ops, NULL));
	req("E0 02 00 05 00 00 00 00");
	TEST_ASSERT_EQUAL(1, rt.ind);
	rt.end_on_frame = true;
	req("E0 02 00 06 00 00 00 00");
	TEST_ASSERT_EQUAL(1, rt.frames);
	TEST_ASSERT_EQUAL(2, rt.ind); /* a new indication, not a lost frame */
	TEST_ASSERT_EQUAL_HEX8(0x06, rt.last[3]);
	TEST_ASSERT_TRUE(sdo_server_busy(srv->node, 0));
	rt.end_on_frame = false;
	TEST_ASSERT_EQUAL(0, sdo_server_route_end(srv->node, 0));
	/* and a plain request after one is answered by the server */
	req("E0 02 00 05 00 00 00 00");
	rt.end_on_frame = true;
	req("40 00 10 00 00 00 00 00");
	EXPECT("43 00 10 00 94 01 04 00");
	TEST_ASSERT_FALSE(sdo_server_busy(srv->node, 0));
	TEST_ASSERT_EQUAL(0, sdo_server_route_attach(srv->node, NULL, NULL));
}

static void test_routing_hook_refusals(void)
{
	memset(&rt, 0, sizeof(rt));
	TEST_ASSERT_EQUAL(0, sdo_server_route_attach(srv->node, &rt_ops, NULL));
	rt.answer = 0x0A000001;
	req("E0 09 00 05 00 00 00 00");
	EXPECT("80 09 00 05 01 00 00 0A");
	TEST_ASSERT_FALSE(sdo_server_busy(srv->node, 0));
	/* the hook answers and releases from inside the indication */
	rt.answer = 0;
	rt.end_inside = true;
	req("E0 0A 00 05 00 00 00 00");
	EXPECT("80 0A 00 05 01 00 00 0A");
	TEST_ASSERT_FALSE(sdo_server_busy(srv->node, 0));
	TEST_ASSERT_EQUAL(2, tb_count_from_id(&bus, 0, 0x581, 0));
}

static void test_reset_ends_a_route(void)
{
	memset(&rt, 0, sizeof(rt));
	TEST_ASSERT_EQUAL(0, sdo_server_route_attach(srv->node, &rt_ops, NULL));
	req("E0 02 00 05 00 00 00 00");
	co_node_reset_comm(srv->node, bus.now);
	TEST_ASSERT_EQUAL(1, rt.ended);
	TEST_ASSERT_FALSE(sdo_server_busy(srv->node, 0));
	TEST_ASSERT_EQUAL(-ENOENT, sdo_server_route_end(srv->node, 0));
}

/* ---- NMT state (CiA 301 §7.3.2.2) and block CRC negotiation ---------- */

static void nmt(const char *hex)
{
	tb_advance(&bus, 1); /* first tick: boot-up, PRE-OPERATIONAL */
	tb_send_hex(&bus, 0x000, hex);
}

/* CiA 301 §7.3.2: in STOPPED only NMT and error control; no SDO answer
 * at all. Before the fix the server answered 43 00 10 00 ... */
static void test_stopped_node_answers_no_sdo(void)
{
	nmt("02 01");
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_STOPPED, co_nmt_get_state(srv->node));
	size_t mark = tb_log_count(&bus);
	req("40 00 10 00 00 00 00 00");
	req("2B 17 10 00 D2 04 00 00");
	req("A4 08 10 00 7F 00 00 00");
	TEST_ASSERT_EQUAL(0, tb_count_from_id(&bus, 0, 0x581, mark));
	uint16_t v;
	TEST_ASSERT_EQUAL(0, co_od_get_u16(srv->od, 0x1017, 0, &v));
	TEST_ASSERT_NOT_EQUAL(1234, v); /* the write was not applied */
	nmt("80 01");                   /* pre-operational: SDO again */
	req("40 00 10 00 00 00 00 00");
	EXPECT("43 00 10 00 94 01 04 00");
}

static void test_stopping_ends_transfer_in_progress(void)
{
	req("40 08 10 00 00 00 00 00");
	EXPECT("41 08 10 00 1B 00 00 00");
	TEST_ASSERT_TRUE(sdo_server_busy(srv->node, 0));
	size_t mark = tb_log_count(&bus);
	nmt("02 00"); /* stop all */
	TEST_ASSERT_FALSE(sdo_server_busy(srv->node, 0));
	TEST_ASSERT_EQUAL(0, tb_count_from_id(&bus, 0, 0x581, mark)); /* no abort frame */
	const co_event *ev = tb_last_event(srv, CO_EV_SDO_SERVER_DONE);
	TEST_ASSERT_NOT_NULL(ev);
	TEST_ASSERT_EQUAL_HEX32(0x08000022, ev->u.sdo_srv.abort);
	req("60 00 00 00 00 00 00 00"); /* the client goes on: still silent */
	TEST_ASSERT_EQUAL(0, tb_count_from_id(&bus, 0, 0x581, mark));
	tb_advance(&bus, 2000000); /* and no timeout abort later either */
	TEST_ASSERT_EQUAL(0, tb_count_from_id(&bus, 0, 0x581, mark));
}

/* Block upload with cc = 0: the server must answer sc = 0 (before the
 * fix: C6 ... i.e. sc = 1, then an end frame with CRC 0). */
static void test_block_upload_without_crc_answers_sc0(void)
{
	req("A0 08 10 00 7F 00 00 00");
	EXPECT("C2 08 10 00 1B 00 00 00");
	req("A3 00 00 00 00 00 00 00");
	EXPECT("84 73 64 75 63 65 72 00");
	req("A2 04 7F 00 00 00 00 00");
	EXPECT("C5 00 00 00 00 00 00 00");
	req("A1 00 00 00 00 00 00 00");
	TEST_ASSERT_EQUAL_HEX32(0, tb_last_event(srv, CO_EV_SDO_SERVER_DONE)->u.sdo_srv.abort);
}

/* Block download with cc = 0: sc = 0 too, and the end frame's CRC field
 * is not checked. */
static void test_block_download_without_crc_answers_sc0(void)
{
	req("C2 00 22 00 00 04 00 00");
	EXPECT("A0 00 22 00 7F 00 00 00");
	send_segments(1024, 0, 127, 0, 0);
	send_segments(1024, 127 * 7, 127, 0, 0);
	EXPECT("A2 14 7F 00 00 00 00 00");
	end_frame(1024, 0);
	EXPECT("A1 00 00 00 00 00 00 00");
	check_domain(1024);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_golden_v1_v2_heartbeat_time);
	RUN_TEST(test_golden_v3_to_v6_real32_write_read);
	RUN_TEST(test_golden_v7_v8_store_save);
	RUN_TEST(test_golden_derived_uploads);
	RUN_TEST(test_golden_abort_missing_object);
	RUN_TEST(test_printed_v3_with_2B_is_too_short);
	RUN_TEST(test_printed_v7_reversed_signature_refused);
	RUN_TEST(test_4_bytes_to_u16_strict_and_lenient);
	RUN_TEST(test_abort_unknown_index_and_sub);
	RUN_TEST(test_abort_read_only_const_write_only);
	RUN_TEST(test_abort_wrong_length);
	RUN_TEST(test_abort_out_of_range);
	RUN_TEST(test_abort_invalid_command_specifier);
	RUN_TEST(test_abort_toggle_segmented_download);
	RUN_TEST(test_abort_toggle_segmented_upload);
	RUN_TEST(test_segmented_download_more_than_announced);
	RUN_TEST(test_abort_refused_by_hook_value_unchanged);
	RUN_TEST(test_abort_timeout_per_frame);
	RUN_TEST(test_client_abort_ends_transfer);
	RUN_TEST(test_short_and_rtr_frames_ignored);
	RUN_TEST(test_segmented_upload_string_1008);
	RUN_TEST(test_segmented_download_string_sets_length);
	RUN_TEST(test_expedited_without_size);
	RUN_TEST(test_block_download_1k_crc_scripted);
	RUN_TEST(test_block_download_lost_and_repeated_segment);
	RUN_TEST(test_block_download_bad_crc);
	RUN_TEST(test_block_download_bad_sequence_number);
	RUN_TEST(test_block_download_too_big_for_object);
	RUN_TEST(test_block_upload_scripted_with_pst_and_crc);
	RUN_TEST(test_block_upload_bad_blksize_and_ack);
	RUN_TEST(test_block_refused_when_disabled);
	RUN_TEST(test_deferred_read_answers_after_continue);
	RUN_TEST(test_deferred_read_still_times_out);
	RUN_TEST(test_deferred_write_commit_and_refuse);
	RUN_TEST(test_deferred_check_at_initiate_for_in_place_domain);
	RUN_TEST(test_deferred_check_at_end_of_streamed_download);
	RUN_TEST(test_upload_sends_the_value_as_it_was_at_the_request);
	RUN_TEST(test_random_frames_fuzz);
	RUN_TEST(test_second_channel_cob_id_rules);
	RUN_TEST(test_two_channels_in_parallel);
	RUN_TEST(test_network_indication_without_hook_is_refused);
	RUN_TEST(test_routing_hook_owns_the_channel_until_released);
	RUN_TEST(test_routing_hook_refusals);
	RUN_TEST(test_frame_left_by_an_ended_route_is_a_new_request);
	RUN_TEST(test_reset_ends_a_route);
	RUN_TEST(test_stopped_node_answers_no_sdo);
	RUN_TEST(test_stopping_ends_transfer_in_progress);
	RUN_TEST(test_block_upload_without_crc_answers_sc0);
	RUN_TEST(test_block_download_without_crc_answers_sc0);
	return UNITY_END();
}
