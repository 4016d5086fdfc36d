/* SPDX-License-Identifier: MIT */
/*
 * SDO client against a scripted server: frame formats (the command
 * specifier follows the size, CiA 301 §7.2.4.3.3), the per-frame timeout driven by the
 * injected clock, remote aborts, queueing, cancel, fallback from block,
 * protocol errors detected by the client.
 */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "unity.h"

#include "core/co.h"
#include "core/crc16.h"
#include "core/sdo_client.h"
#include "tests/unit/support/test_bus.h"

static tb_bus bus;
static tb_port *cli;
static uint8_t buf[256];

void setUp(void)
{
	co_node_config cfg = { .node_id = 1, .sdo_client_count = 2, .sdo_client_queue_len = 3 };
	co_od *od;

	tb_init(&bus);
	TEST_ASSERT_EQUAL(0, co_od_create(&od, 8));
	cli = tb_add_node(&bus, &cfg, od);
	TEST_ASSERT_NOT_NULL(cli);
	memset(buf, 0, sizeof(buf));
}

void tearDown(void)
{
	tb_fini(&bus);
}

#define EXPECT_REQ(id, hex) TB_ASSERT_LAST(&bus, 0, id, hex)

static void reply(const char *hex)
{
	tb_send_hex(&bus, 0x585, hex);
}

static const co_event *done(void)
{
	return tb_last_event(cli, CO_EV_SDO_CLIENT_DONE);
}

static int write_n(const uint8_t *data, uint32_t n, uint64_t tag)
{
	return sdo_client_write(cli->node, 0, 5, 0x2000, 1, data, n, 500, tag, bus.now);
}

/* ---- frame formats ------------------------------------------------------------ */

static void test_expedited_command_specifier_follows_size(void)
{
	static const uint8_t d[4] = { 0x11, 0x22, 0x33, 0x44 };
	static const char *const want[] = { "2F 00 20 01 11 00 00 00", "2B 00 20 01 11 22 00 00",
					    "27 00 20 01 11 22 33 00", "23 00 20 01 11 22 33 44" };

	for (uint32_t n = 1; n <= 4; n++) {
		TEST_ASSERT_EQUAL(0, write_n(d, n, n));
		EXPECT_REQ(0x605, want[n - 1]);
		reply("60 00 20 01 00 00 00 00");
		TEST_ASSERT_EQUAL_HEX32(0, done()->u.sdo_cli.abort);
		TEST_ASSERT_EQUAL_UINT64(n, done()->u.sdo_cli.tag);
		TEST_ASSERT_EQUAL(SDO_MODE_EXPEDITED, done()->u.sdo_cli.mode);
	}
}

static void test_golden_read_1000_from_simulated_slave(void)
{
	uint32_t v;

	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 0, 5, 0x1000, 0, buf, 4, 0, 42, bus.now));
	EXPECT_REQ(0x605, "40 00 10 00 00 00 00 00");
	reply("43 00 10 00 94 01 04 00");
	TEST_ASSERT_EQUAL_HEX32(0, done()->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL_UINT32(4, done()->u.sdo_cli.size);
	TEST_ASSERT_EQUAL_UINT64(42, done()->u.sdo_cli.tag);
	TEST_ASSERT_EQUAL(5, done()->u.sdo_cli.node_id);
	TEST_ASSERT_EQUAL_PTR(buf, done()->u.sdo_cli.data);
	TEST_ASSERT_EQUAL_HEX32(0x00040194, co_get_le32(buf));
	/* The client channel's OD entries show the target. */
	TEST_ASSERT_EQUAL(0, co_od_get_u32(cli->od, 0x1280, 1, &v));
	TEST_ASSERT_EQUAL_HEX32(0x605, v);
	TEST_ASSERT_EQUAL(0, co_od_get_u32(cli->od, 0x1280, 2, &v));
	TEST_ASSERT_EQUAL_HEX32(0x585, v);
}

/* A second answer to a request already answered (two devices on node 5):
 * reported once as CO_EV_SDO_CLIENT_SECOND_ANSWER, with the idle channel
 * or before the next transfer's own answer; the next transfer is not
 * disturbed by it. Past the timeout, or naming another object, it is not. */
static void test_second_answer_reported(void)
{
	uint32_t v = 0;

	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 0, 5, 0x1000, 0, buf, 4, 500, 1, bus.now));
	reply("43 00 10 00 94 01 04 00");
	TEST_ASSERT_EQUAL_HEX32(0, done()->u.sdo_cli.abort);
	reply("43 00 10 00 94 01 04 00"); /* the twin, channel idle */
	TEST_ASSERT_EQUAL(1, tb_event_count(cli, CO_EV_SDO_CLIENT_SECOND_ANSWER));
	const co_event *e = tb_last_event(cli, CO_EV_SDO_CLIENT_SECOND_ANSWER);
	TEST_ASSERT_EQUAL_UINT8(5, e->u.sdo_cli.node_id);
	TEST_ASSERT_EQUAL_HEX16(0x1000, e->u.sdo_cli.index);
	TEST_ASSERT_EQUAL_UINT8(0, e->u.sdo_cli.sub);

	/* the next read runs when the twin's answer to the previous one comes */
	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 0, 5, 0x1018, 1, buf, 4, 500, 2, bus.now));
	reply("43 00 10 00 94 01 04 00");
	TEST_ASSERT_EQUAL(2, tb_event_count(cli, CO_EV_SDO_CLIENT_SECOND_ANSWER));
	TEST_ASSERT_EQUAL(1, tb_event_count(cli, CO_EV_SDO_CLIENT_DONE));
	reply("43 18 10 01 50 02 00 00");
	TEST_ASSERT_EQUAL_HEX32(0, done()->u.sdo_cli.abort);
	memcpy(&v, buf, 4);
	TEST_ASSERT_EQUAL_HEX32(0x250, v);

	/* an answer naming another object, or one after the timeout: no */
	reply("43 00 10 00 94 01 04 00");
	tb_advance(&bus, 600 * 1000);
	reply("43 18 10 01 50 02 00 00");
	TEST_ASSERT_EQUAL(2, tb_event_count(cli, CO_EV_SDO_CLIENT_SECOND_ANSWER));
}

static void test_golden_writes_v1_v3_v7(void)
{
	static const uint8_t hb[2] = { 0xA0, 0x0F };
	static const uint8_t zero[4] = { 0xA4, 0x70, 0x9D, 0x3F };
	static const uint8_t save[4] = { 's', 'a', 'v', 'e' };

	sdo_client_write(cli->node, 0, 1, 0x1017, 0, hb, 2, 0, 1, bus.now);
	TB_ASSERT_LAST(&bus, 0, 0x601, "2B 17 10 00 A0 0F 00 00");
	tb_send_hex(&bus, 0x581, "60 17 10 00 00 00 00 00");
	sdo_client_write(cli->node, 0, 1, 0x2004, 1, zero, 4, 0, 2, bus.now);
	TB_ASSERT_LAST(&bus, 0, 0x601, "23 04 20 01 A4 70 9D 3F");
	tb_send_hex(&bus, 0x581, "60 04 20 01 00 00 00 00");
	sdo_client_write(cli->node, 0, 1, 0x1010, 1, save, 4, 0, 3, bus.now);
	TB_ASSERT_LAST(&bus, 0, 0x601, "23 10 10 01 73 61 76 65");
	tb_send_hex(&bus, 0x581, "60 10 10 01 00 00 00 00");
	TEST_ASSERT_EQUAL(3, tb_event_count(cli, CO_EV_SDO_CLIENT_DONE));
	TEST_ASSERT_EQUAL_HEX32(0, done()->u.sdo_cli.abort);
}

static void test_segmented_download_frames(void)
{
	static const uint8_t d[10] = "0123456789";
	sdo_client_req r = { .node_id = 5,
			     .index = 0x2000,
			     .sub = 1,
			     .data = d,
			     .size = 10,
			     .mode = SDO_MODE_SEGMENTED };

	TEST_ASSERT_EQUAL(0, sdo_client_submit(cli->node, 0, &r, bus.now));
	EXPECT_REQ(0x605, "21 00 20 01 0A 00 00 00");
	reply("60 00 20 01 00 00 00 00");
	EXPECT_REQ(0x605, "00 30 31 32 33 34 35 36");
	reply("20 00 00 00 00 00 00 00");
	EXPECT_REQ(0x605, "19 37 38 39 00 00 00 00");
	reply("30 00 00 00 00 00 00 00");
	TEST_ASSERT_EQUAL_HEX32(0, done()->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL_UINT32(10, done()->u.sdo_cli.size);
}

static void test_client_detects_toggle_error(void)
{
	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 0, 5, 0x1008, 0, buf, 64, 0, 1, bus.now));
	reply("41 08 10 00 0E 00 00 00");
	EXPECT_REQ(0x605, "60 00 00 00 00 00 00 00");
	reply("00 41 42 43 44 45 46 47");
	EXPECT_REQ(0x605, "70 00 00 00 00 00 00 00");
	reply("00 41 42 43 44 45 46 47"); /* toggle should be 1 */
	EXPECT_REQ(0x605, "80 08 10 00 00 00 03 05");
	TEST_ASSERT_EQUAL_HEX32(0x05030000, done()->u.sdo_cli.abort);
}

static void test_client_detects_size_mismatch_and_bad_command(void)
{
	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 0, 5, 0x1008, 0, buf, 64, 0, 1, bus.now));
	reply("41 08 10 00 03 00 00 00"); /* announces 3 */
	reply("01 41 42 43 44 45 46 47"); /* sends 7 */
	TEST_ASSERT_EQUAL_HEX32(0x06070010, done()->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 0, 5, 0x1008, 0, buf, 64, 0, 2, bus.now));
	reply("60 08 10 00 00 00 00 00"); /* a download answer to an upload */
	EXPECT_REQ(0x605, "80 08 10 00 01 00 04 05");
	TEST_ASSERT_EQUAL_HEX32(0x05040001, done()->u.sdo_cli.abort);
}

/* An answer naming another object (3005h for a request
 * for 3004h) aborts at once with 06040043; before, it was ignored and the
 * request timed out. */
static void test_answer_for_other_object_aborts_at_once(void)
{
	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 0, 5, 0x3004, 0, buf, 4, 0, 1, bus.now));
	reply("43 05 30 00 01 00 00 00");
	EXPECT_REQ(0x605, "80 04 30 00 43 00 04 06");
	TEST_ASSERT_NOT_NULL(done());
	TEST_ASSERT_EQUAL_HEX32(0x06040043, done()->u.sdo_cli.abort);
	/* the same for downloads and block initiates */
	static const uint8_t d[200] = { 1 };
	TEST_ASSERT_EQUAL(0, write_n(d, 2, 2));
	reply("60 01 20 01 00 00 00 00");
	TEST_ASSERT_EQUAL_HEX32(0x06040043, done()->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL(0, write_n(d, 200, 3)); /* block (threshold 128) */
	reply("A4 00 20 02 7F 00 00 00");
	TEST_ASSERT_EQUAL_UINT64(3, done()->u.sdo_cli.tag);
	TEST_ASSERT_EQUAL_HEX32(0x06040043, done()->u.sdo_cli.abort);
}

/* What the old test "stale answer with other index is ignored" meant: the
 * late answer of a request this channel cancelled does not disturb the
 * next one. */
static void test_stale_answer_of_cancelled_request_is_ignored(void)
{
	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 0, 5, 0x1018, 1, buf, 4, 0, 1, bus.now));
	TEST_ASSERT_EQUAL(0, sdo_client_cancel(cli->node, 0, 1, 0x08000000, bus.now));
	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 0, 5, 0x1000, 0, buf, 4, 0, 2, bus.now));
	reply("43 18 10 01 50 02 00 00"); /* answer to the cancelled request */
	TEST_ASSERT_EQUAL_UINT64(1, done()->u.sdo_cli.tag);
	reply("43 00 10 00 94 01 04 00");
	TEST_ASSERT_EQUAL_UINT64(2, done()->u.sdo_cli.tag);
	TEST_ASSERT_EQUAL_HEX32(0, done()->u.sdo_cli.abort);
}

/* An upload cancelled before the server answered its initiate, and the
 * same object asked again at once: the server's late answer to the first
 * would look like the answer to the second (same object, same kind), so
 * the second goes out only once the server has been quiet for the settle
 * time (100 ms), each of its frames starting that time again. Before, it
 * went out at once and took the late answer as its own (the stress test's
 * 05040001 when the real answer came next). */
static void test_same_object_after_unanswered_cancel_waits_for_quiet(void)
{
	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 0, 5, 0x2100, 0, buf, 64, 0, 1, bus.now));
	EXPECT_REQ(0x605, "40 00 21 00 00 00 00 00");
	TEST_ASSERT_EQUAL(0, sdo_client_cancel(cli->node, 0, 1, 0x08000000, bus.now));
	TEST_ASSERT_EQUAL_UINT64(1, done()->u.sdo_cli.tag);
	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 0, 5, 0x2100, 0, buf, 64, 0, 2, bus.now));
	EXPECT_REQ(0x605, "80 00 21 00 00 00 00 08"); /* not yet sent */
	tb_advance(&bus, 60 * 1000);
	reply("41 00 21 00 1B 00 00 00"); /* the late answer to the first */
	tb_advance(&bus, 60 * 1000);
	EXPECT_REQ(0x605, "80 00 21 00 00 00 00 08"); /* quiet for 60 ms only */
	TEST_ASSERT_EQUAL_STRING("idle", sdo_client_state_to_string(cli->node, 0));
	tb_advance(&bus, 40 * 1000);
	EXPECT_REQ(0x605, "40 00 21 00 00 00 00 00");
	reply("43 00 21 00 61 62 63 64");
	TEST_ASSERT_EQUAL_UINT64(2, done()->u.sdo_cli.tag);
	TEST_ASSERT_EQUAL_HEX32(0, done()->u.sdo_cli.abort);
	/* another object of the same server does not wait: is_stale tells
	 * a late answer naming the old one apart */
	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 0, 5, 0x2100, 0, buf, 64, 0, 3, bus.now));
	TEST_ASSERT_EQUAL(0, sdo_client_cancel(cli->node, 0, 3, 0x08000000, bus.now));
	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 0, 5, 0x1000, 0, buf, 4, 0, 4, bus.now));
	EXPECT_REQ(0x605, "40 00 10 00 00 00 00 00");
}

/* A segmented upload cancelled (its client died) while
 * the server's next segment was on its way. The cancel puts an abort on
 * the bus; the new upload ignores the late segments (before the fix it
 * aborted 05040001 on them). */
static void test_late_segments_of_cancelled_upload_do_not_poison_next(void)
{
	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 0, 5, 0x1008, 0, buf, 64, 0, 1, bus.now));
	reply("41 08 10 00 1B 00 00 00");
	reply("00 41 42 43 44 45 46 47");
	EXPECT_REQ(0x605, "70 00 00 00 00 00 00 00");
	TEST_ASSERT_EQUAL(0, sdo_client_cancel(cli->node, 0, 1, 0x08000000, bus.now));
	TEST_ASSERT_TRUE(tb_frame_is(tb_log_at(&bus, tb_log_count(&bus) - 1), 0x605,
				     "80 08 10 00 00 00 00 08"));
	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 1, 5, 0x1008, 0, buf, 64, 0, 2, bus.now));
	EXPECT_REQ(0x605, "40 08 10 00 00 00 00 00");
	reply("10 48 49 4A 4B 4C 4D 4E"); /* late segment of the cancelled one */
	reply("00 48 49 4A 4B 4C 4D 4E");
	TEST_ASSERT_EQUAL_UINT64(1, done()->u.sdo_cli.tag);
	reply("43 08 10 00 61 62 63 64"); /* 4-byte value: expedited */
	TEST_ASSERT_EQUAL_UINT64(2, done()->u.sdo_cli.tag);
	TEST_ASSERT_EQUAL_HEX32(0, done()->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL_UINT32(4, done()->u.sdo_cli.size);
	/* Once the new transfer has its answer, the filter is gone: a
	 * segment now is a protocol error again. */
	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 1, 5, 0x1008, 0, buf, 64, 0, 3, bus.now));
	reply("00 48 49 4A 4B 4C 4D 4E");
	TEST_ASSERT_EQUAL_HEX32(0x05040001, done()->u.sdo_cli.abort);
}

/* The same for a block upload: its sub-block segments carry any byte 0. */
static void test_late_block_segments_of_cancelled_upload_ignored(void)
{
	sdo_client_req r = { .upload = true,
			     .node_id = 5,
			     .index = 0x2200,
			     .sub = 0,
			     .mode = SDO_MODE_BLOCK,
			     .tag = 1,
			     .buf = buf,
			     .cap = sizeof(buf) };
	TEST_ASSERT_EQUAL(0, sdo_client_submit(cli->node, 0, &r, bus.now));
	reply("C6 00 22 00 00 01 00 00");
	reply("01 01 02 03 04 05 06 07");
	TEST_ASSERT_EQUAL(0, sdo_client_cancel(cli->node, 0, 1, 0x08000000, bus.now));
	r.tag = 2;
	TEST_ASSERT_EQUAL(0, sdo_client_submit(cli->node, 0, &r, bus.now));
	reply("02 01 02 03 04 05 06 07");
	reply("43 41 42 43 44 45 46 47"); /* looks like an init answer... */
	reply("85 48 49 4A 00 00 00 00"); /* ...and an abort: late segments */
	TEST_ASSERT_EQUAL_UINT64(1, done()->u.sdo_cli.tag);
	reply("C6 00 22 00 07 00 00 00");
	EXPECT_REQ(0x605, "A3 00 00 00 00 00 00 00");
}

/* ---- NMT state (CiA 301 §7.3.2.2) -------------------------------------- */

static void own_nmt(const char *hex)
{
	tb_advance(&bus, 1); /* first tick: boot-up, PRE-OPERATIONAL */
	tb_send_hex(&bus, 0x000, hex);
}

static void test_stopped_node_sends_no_sdo(void)
{
	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 0, 5, 0x1008, 0, buf, 64, 0, 1, bus.now));
	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 0, 5, 0x1000, 0, buf, 64, 0, 2, bus.now));
	reply("41 08 10 00 1B 00 00 00");
	size_t mark = tb_log_count(&bus);
	own_nmt("02 01");
	/* the running one ends at once, the queued one from the next tick;
	 * both with "device state", without a frame */
	tb_advance(&bus, 1);
	TEST_ASSERT_EQUAL(2, tb_event_count(cli, CO_EV_SDO_CLIENT_DONE));
	TEST_ASSERT_EQUAL_UINT64(2, done()->u.sdo_cli.tag);
	TEST_ASSERT_EQUAL_HEX32(0x08000022, done()->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL(0, tb_count_from_id(&bus, 0, 0x605, mark));
	TEST_ASSERT_EQUAL(0, sdo_client_pending(cli->node, 0));
	/* a new request is refused the same way */
	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 1, 5, 0x1000, 0, buf, 64, 0, 3, bus.now));
	tb_advance(&bus, 1);
	TEST_ASSERT_EQUAL_UINT64(3, done()->u.sdo_cli.tag);
	TEST_ASSERT_EQUAL_HEX32(0x08000022, done()->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL(0, tb_count_from_id(&bus, 0, 0x605, mark));
	tb_advance(&bus, 3000000);
	TEST_ASSERT_EQUAL(0, tb_count_from_id(&bus, 0, 0x605, mark));
	/* pre-operational: allowed again */
	tb_send_hex(&bus, 0x000, "80 01");
	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 1, 5, 0x1000, 0, buf, 64, 0, 4, bus.now));
	EXPECT_REQ(0x605, "40 00 10 00 00 00 00 00");
}

/* ---- timeouts -------------------------------------------------------------- */

static void test_silent_slave_times_out_exactly(void)
{
	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 0, 5, 0x1000, 0, buf, 4, 500, 9, bus.now));
	TEST_ASSERT_TRUE(co_node_next_deadline_us(cli->node) <= bus.now + 500000);
	tb_advance(&bus, 499999);
	TEST_ASSERT_NULL(done());
	tb_advance(&bus, 1);
	TEST_ASSERT_NOT_NULL(done());
	TEST_ASSERT_EQUAL_HEX32(0x05040000, done()->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL_UINT64(9, done()->u.sdo_cli.tag);
	EXPECT_REQ(0x605, "80 00 10 00 00 00 04 05");
}

static void test_timeout_restarts_on_every_frame(void)
{
	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 0, 5, 0x1008, 0, buf, 64, 500, 1, bus.now));
	tb_advance(&bus, 499999);
	reply("41 08 10 00 15 00 00 00"); /* 21 bytes */
	for (int i = 0; i < 3; i++) {
		tb_advance(&bus, 499999);
		TEST_ASSERT_NULL(done());
		reply(i % 2 ? "10 61 62 63 64 65 66 67" : "00 61 62 63 64 65 66 67");
	}
	/* 21 bytes delivered in 3 segments without c: one more request. */
	TEST_ASSERT_NULL(done());
	tb_advance(&bus, 500000);
	TEST_ASSERT_EQUAL_HEX32(0x05040000, done()->u.sdo_cli.abort);
}

/* ---- aborts, queue, cancel ---------------------------------------------------- */

static void test_remote_abort_code_in_event(void)
{
	TEST_ASSERT_EQUAL(0, sdo_client_read(cli->node, 0, 5, 0x2001, 0, buf, 4, 0, 1, bus.now));
	reply("80 01 20 00 00 00 02 06");
	TEST_ASSERT_EQUAL_HEX32(0x06020000, done()->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL_STRING("object does not exist",
				 sdo_abort_to_string(done()->u.sdo_cli.abort));
	/* No abort frame in answer to an abort. */
	TB_ASSERT_LAST(&bus, 0, 0x605, "40 01 20 00 00 00 00 00");
}

static void test_queue_never_busy_until_capacity(void)
{
	static const uint8_t d[1] = { 1 };

	TEST_ASSERT_EQUAL(0, write_n(d, 1, 1)); /* runs */
	TEST_ASSERT_EQUAL(0, write_n(d, 1, 2)); /* queued 1/3 */
	TEST_ASSERT_EQUAL(0, write_n(d, 1, 3));
	TEST_ASSERT_EQUAL(0, write_n(d, 1, 4));
	TEST_ASSERT_EQUAL(-ENOSPC, write_n(d, 1, 5));
	TEST_ASSERT_EQUAL(4, sdo_client_pending(cli->node, 0));
	TEST_ASSERT_EQUAL_STRING("download initiate", sdo_client_state_to_string(cli->node, 0));
	TEST_ASSERT_EQUAL_STRING("?", sdo_client_state_to_string(cli->node, 200));
	size_t before = tb_count_from_id(&bus, 0, 0x605, 0);
	TEST_ASSERT_EQUAL(1, before); /* never two requests on the wire */
	for (uint64_t t = 1; t <= 4; t++) {
		reply("60 00 20 01 00 00 00 00");
		TEST_ASSERT_EQUAL_UINT64(t, done()->u.sdo_cli.tag);
	}
	TEST_ASSERT_EQUAL(4, tb_count_from_id(&bus, 0, 0x605, 0));
	TEST_ASSERT_EQUAL(0, sdo_client_pending(cli->node, 0));
	TEST_ASSERT_EQUAL_STRING("idle", sdo_client_state_to_string(cli->node, 0));
}

static void test_cancel_running_and_queued(void)
{
	static const uint8_t d[1] = { 1 };

	write_n(d, 1, 10);
	write_n(d, 1, 11);
	write_n(d, 1, 12);
	TEST_ASSERT_EQUAL(0, sdo_client_cancel(cli->node, 0, 11, 0x08000000, bus.now));
	TEST_ASSERT_EQUAL_UINT64(11, done()->u.sdo_cli.tag);
	TEST_ASSERT_EQUAL_HEX32(0x08000000, done()->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL(0, sdo_client_cancel(cli->node, 0, 10, 0x08000000, bus.now));
	/* 12 writes the object whose initiate 10 left unanswered: it starts
	 * once the server has been quiet for the settle time, so that a late
	 * answer to 10 cannot confirm it */
	EXPECT_REQ(0x605, "80 00 20 01 00 00 00 08");
	tb_advance(&bus, 100 * 1000);
	EXPECT_REQ(0x605, "2F 00 20 01 01 00 00 00");
	TEST_ASSERT_EQUAL(-ENOENT, sdo_client_cancel(cli->node, 0, 99, 0x08000000, bus.now));
	TEST_ASSERT_EQUAL(-EINVAL, sdo_client_cancel(cli->node, 7, 99, 0x08000000, bus.now));
}

static void test_same_target_on_two_channels_waits(void)
{
	static const uint8_t d[1] = { 1 };

	write_n(d, 1, 1);
	TEST_ASSERT_EQUAL(0, sdo_client_write(cli->node, 1, 5, 0x2000, 2, d, 1, 0, 2, bus.now));
	TEST_ASSERT_EQUAL(1, tb_count_from_id(&bus, 0, 0x605, 0));
	reply("60 00 20 01 00 00 00 00");
	TEST_ASSERT_EQUAL_UINT64(1, done()->u.sdo_cli.tag);
	EXPECT_REQ(0x605, "2F 00 20 02 01 00 00 00");
	reply("60 00 20 02 00 00 00 00");
	TEST_ASSERT_EQUAL_UINT64(2, done()->u.sdo_cli.tag);
	TEST_ASSERT_EQUAL(1, done()->u.sdo_cli.channel);
}

static void test_invalid_requests(void)
{
	sdo_client_req r = { .node_id = 0, .index = 0x1000, .upload = true, .buf = buf, .cap = 4 };

	TEST_ASSERT_EQUAL(-EINVAL, sdo_client_submit(cli->node, 0, &r, bus.now));
	r.node_id = 128;
	TEST_ASSERT_EQUAL(-EINVAL, sdo_client_submit(cli->node, 0, &r, bus.now));
	r.node_id = 5;
	TEST_ASSERT_EQUAL(-EINVAL, sdo_client_submit(cli->node, 2, &r, bus.now));
	r = (sdo_client_req){ .node_id = 5, .index = 0x1000, .size = 4 }; /* no data */
	TEST_ASSERT_EQUAL(-EINVAL, sdo_client_submit(cli->node, 0, &r, bus.now));
	/* Explicit COB-IDs (a gateway's routed client): any node-id. */
	r = (sdo_client_req){ .upload = true,
			      .index = 0x1000,
			      .buf = buf,
			      .cap = 4,
			      .cob_req = 0x640,
			      .cob_resp = 0x5C0 };
	TEST_ASSERT_EQUAL(0, sdo_client_submit(cli->node, 0, &r, bus.now));
	EXPECT_REQ(0x640, "40 00 10 00 00 00 00 00");
	tb_send_hex(&bus, 0x5C0, "4F 00 10 00 07 00 00 00");
	TEST_ASSERT_EQUAL_HEX32(0, done()->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL_UINT8(7, buf[0]);
}

/* ---- block, scripted ------------------------------------------------------------ */

static void test_block_refused_falls_back_to_segmented(void)
{
	static uint8_t d[200];
	sdo_client_req r = { .node_id = 5, .index = 0x2000, .sub = 1, .data = d, .size = 200 };

	for (unsigned i = 0; i < sizeof(d); i++)
		d[i] = (uint8_t)i;
	TEST_ASSERT_EQUAL(0, sdo_client_submit(cli->node, 0, &r, bus.now)); /* AUTO */
	EXPECT_REQ(0x605, "C6 00 20 01 C8 00 00 00");
	reply("80 00 20 01 01 00 04 05"); /* unknown command: no block support */
	EXPECT_REQ(0x605, "21 00 20 01 C8 00 00 00");
	TEST_ASSERT_NULL(done());
	reply("60 00 20 01 00 00 00 00");
	for (int i = 0; i < 29; i++) /* 200 bytes = 28 x 7 + 4 */
		reply(i % 2 ? "30 00 00 00 00 00 00 00" : "20 00 00 00 00 00 00 00");
	TEST_ASSERT_NOT_NULL(done());
	TEST_ASSERT_EQUAL_HEX32(0, done()->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL(SDO_MODE_SEGMENTED, done()->u.sdo_cli.mode);
	/* Other refusals are final. */
	TEST_ASSERT_EQUAL(0, sdo_client_submit(cli->node, 0, &r, bus.now));
	reply("80 00 20 01 00 00 02 06");
	TEST_ASSERT_EQUAL_HEX32(0x06020000, done()->u.sdo_cli.abort);
}

static void test_block_download_scripted_frames(void)
{
	static uint8_t d[10] = "abcdefghij";
	sdo_client_req r = { .node_id = 5,
			     .index = 0x2000,
			     .sub = 1,
			     .data = d,
			     .size = 10,
			     .mode = SDO_MODE_BLOCK };
	char hex[64];
	uint16_t crc = crc16_ccitt(0, d, 10);

	TEST_ASSERT_EQUAL(0, sdo_client_submit(cli->node, 0, &r, bus.now));
	EXPECT_REQ(0x605, "C6 00 20 01 0A 00 00 00");
	reply("A4 00 20 01 05 00 00 00"); /* blksize 5 */
	TEST_ASSERT_TRUE(tb_frame_is(tb_log_at(&bus, tb_log_count(&bus) - 2), 0x605,
				     "01 61 62 63 64 65 66 67"));
	EXPECT_REQ(0x605, "82 68 69 6A 00 00 00 00");
	reply("A2 01 05 00 00 00 00 00"); /* only segment 1 arrived */
	EXPECT_REQ(0x605, "81 68 69 6A 00 00 00 00");
	reply("A2 01 05 00 00 00 00 00");
	snprintf(hex, sizeof(hex), "D1 %02X %02X 00 00 00 00 00", crc & 0xFF, crc >> 8);
	EXPECT_REQ(0x605, hex); /* n = 4 */
	reply("A1 00 00 00 00 00 00 00");
	TEST_ASSERT_EQUAL_HEX32(0, done()->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL(SDO_MODE_BLOCK, done()->u.sdo_cli.mode);
	TEST_ASSERT_EQUAL_UINT32(10, done()->u.sdo_cli.size);
}

static void test_block_download_server_bad_ack(void)
{
	static uint8_t d[10];
	sdo_client_req r = { .node_id = 5,
			     .index = 0x2000,
			     .sub = 1,
			     .data = d,
			     .size = 10,
			     .mode = SDO_MODE_BLOCK };

	TEST_ASSERT_EQUAL(0, sdo_client_submit(cli->node, 0, &r, bus.now));
	reply("A4 00 20 01 00 00 00 00"); /* blksize 0 */
	TEST_ASSERT_EQUAL_HEX32(0x05040002, done()->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL(0, sdo_client_submit(cli->node, 0, &r, bus.now));
	reply("A4 00 20 01 7F 00 00 00");
	reply("A2 05 7F 00 00 00 00 00"); /* acks 5 of 2 */
	TEST_ASSERT_EQUAL_HEX32(0x05040003, done()->u.sdo_cli.abort);
}

static void test_block_upload_scripted_crc_error(void)
{
	sdo_client_req r = { .upload = true,
			     .node_id = 5,
			     .index = 0x2000,
			     .sub = 1,
			     .buf = buf,
			     .cap = sizeof(buf),
			     .mode = SDO_MODE_BLOCK };

	TEST_ASSERT_EQUAL(0, sdo_client_submit(cli->node, 0, &r, bus.now));
	EXPECT_REQ(0x605, "A4 00 20 01 7F 00 00 00"); /* pst 0: explicit block */
	reply("C6 00 20 01 09 00 00 00");
	EXPECT_REQ(0x605, "A3 00 00 00 00 00 00 00");
	reply("01 61 62 63 64 65 66 67");
	reply("03 00 00 00 00 00 00 00"); /* 2 lost */
	reply("82 68 69 00 00 00 00 00"); /* 2 again, last */
	EXPECT_REQ(0x605, "A2 02 7F 00 00 00 00 00");
	reply("D5 00 00 00 00 00 00 00"); /* n = 5, CRC 0: wrong */
	EXPECT_REQ(0x605, "80 00 20 01 04 00 04 05");
	TEST_ASSERT_EQUAL_HEX32(0x05040004, done()->u.sdo_cli.abort);
}

static void test_block_upload_scripted_ok_with_resend(void)
{
	sdo_client_req r = { .upload = true,
			     .node_id = 5,
			     .index = 0x2000,
			     .sub = 1,
			     .buf = buf,
			     .cap = sizeof(buf),
			     .mode = SDO_MODE_BLOCK };
	uint16_t crc = crc16_ccitt(0, "abcdefghi", 9);
	char hex[64];

	TEST_ASSERT_EQUAL(0, sdo_client_submit(cli->node, 0, &r, bus.now));
	reply("C6 00 20 01 09 00 00 00");
	reply("01 61 62 63 64 65 66 67");
	reply("01 61 62 63 64 65 66 67"); /* repeated: ignored */
	reply("82 68 69 00 00 00 00 00");
	EXPECT_REQ(0x605, "A2 02 7F 00 00 00 00 00");
	snprintf(hex, sizeof(hex), "D5 %02X %02X 00 00 00 00 00", crc & 0xFF, crc >> 8);
	reply(hex);
	EXPECT_REQ(0x605, "A1 00 00 00 00 00 00 00");
	TEST_ASSERT_EQUAL_HEX32(0, done()->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL_UINT32(9, done()->u.sdo_cli.size);
	TEST_ASSERT_EQUAL_MEMORY("abcdefghi", buf, 9);
}

/* Garbage answers never crash the client; every request completes. */
static void test_random_answers_fuzz(void)
{
	static const uint8_t cs[] = { 0x00, 0x10, 0x20, 0x30, 0x41, 0x43, 0x60, 0x80, 0xA0,
				      0xA1, 0xA2, 0xA4, 0xC0, 0xC1, 0xC4, 0xC6, 0x01, 0x82 };
	static uint8_t d[3000];
	uint32_t seed = 777;
	size_t started = 0;

	bus.log_on = false;
	for (int round = 0; round < 3000; round++) {
		sdo_client_req r = { .node_id = 5,
				     .index = 0x2000,
				     .sub = 1,
				     .timeout_ms = 100,
				     .mode = (uint8_t)(round % 4),
				     .tag = (uint64_t)round };
		if (round & 1) {
			r.upload = true;
			r.buf = buf;
			r.cap = sizeof(buf);
			r.size = (round & 2) ? 2000 : 0;
		} else {
			r.data = d;
			r.size = (uint32_t)(round * 7) % sizeof(d);
		}
		TEST_ASSERT_EQUAL(0, sdo_client_submit(cli->node, 0, &r, bus.now));
		started++;
		for (int k = 0; k < 40 && sdo_client_pending(cli->node, 0); k++) {
			uint8_t f[8];
			char hex[32];
			seed = seed * 1664525u + 1013904223u;
			for (int j = 0; j < 8; j++)
				f[j] = (uint8_t)(seed >> (j * 3));
			if (seed & 0x100) {
				f[0] = cs[(seed >> 9) % sizeof(cs)];
				f[1] = 0x00;
				f[2] = 0x20;
				f[3] = 0x01;
			}
			snprintf(hex, sizeof(hex), "%02X %02X %02X %02X %02X %02X %02X %02X", f[0],
				 f[1], f[2], f[3], f[4], f[5], f[6], f[7]);
			reply(hex);
		}
		tb_advance(&bus, 200000); /* whatever is left times out */
		TEST_ASSERT_EQUAL(0, sdo_client_pending(cli->node, 0));
	}
	TEST_ASSERT_EQUAL(3000, started);
	bus.log_on = true;
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_expedited_command_specifier_follows_size);
	RUN_TEST(test_golden_read_1000_from_simulated_slave);
	RUN_TEST(test_second_answer_reported);
	RUN_TEST(test_golden_writes_v1_v3_v7);
	RUN_TEST(test_segmented_download_frames);
	RUN_TEST(test_client_detects_toggle_error);
	RUN_TEST(test_client_detects_size_mismatch_and_bad_command);
	RUN_TEST(test_answer_for_other_object_aborts_at_once);
	RUN_TEST(test_stale_answer_of_cancelled_request_is_ignored);
	RUN_TEST(test_same_object_after_unanswered_cancel_waits_for_quiet);
	RUN_TEST(test_late_segments_of_cancelled_upload_do_not_poison_next);
	RUN_TEST(test_late_block_segments_of_cancelled_upload_ignored);
	RUN_TEST(test_stopped_node_sends_no_sdo);
	RUN_TEST(test_silent_slave_times_out_exactly);
	RUN_TEST(test_timeout_restarts_on_every_frame);
	RUN_TEST(test_remote_abort_code_in_event);
	RUN_TEST(test_queue_never_busy_until_capacity);
	RUN_TEST(test_cancel_running_and_queued);
	RUN_TEST(test_same_target_on_two_channels_waits);
	RUN_TEST(test_invalid_requests);
	RUN_TEST(test_block_refused_falls_back_to_segmented);
	RUN_TEST(test_block_download_scripted_frames);
	RUN_TEST(test_block_download_server_bad_ack);
	RUN_TEST(test_block_upload_scripted_crc_error);
	RUN_TEST(test_block_upload_scripted_ok_with_resend);
	RUN_TEST(test_random_answers_fuzz);
	return UNITY_END();
}
