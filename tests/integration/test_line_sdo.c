/* SPDX-License-Identifier: MIT */
/*
 * Mailbox SDO transfers through a real line thread (lines/line_sdo.c and
 * the SDO client pool) over vcan0, with this test playing the SDO servers
 * on the bus:
 * - a read is answered with the server's data;
 * - the pool: a transfer to a silent node does not hold back one to
 *   another node (both on the wire at once);
 * - the per-frame timeout of a transfer that gives none is the SDO
 *   client's setting, not the SDO server's (review defect);
 * - a client that goes away has exactly its own transfer cancelled; the
 *   other client's transfer goes on (review defect: the pending slot did
 *   not know its transfer and the cancel went to every channel).
 */
#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "unity.h"

#include "core/co.h"
#include "core/sdo.h"
#include "lines/line.h"
#include "lines/socketcan.h"
#include "mailbox/cogw.h"
#include "mailbox/proto.h"

#define CLIENT_TIMEOUT_MS 300u
#define SERVER_TIMEOUT_MS 5000u

static co_od *od;
static line *ln;
static can_port *bus; /* the SDO servers' side */
static char instance[32], qname[MBX_QNAME_MAX];
/* SDO request frames (600h + node) seen on the bus and not yet taken. */
static co_frame seen[64];
static unsigned n_seen;

void setUp(void)
{
	snprintf(instance, sizeof instance, "lsdo%d", (int)getpid());
	TEST_ASSERT_EQUAL(0, mbx_queue_name(qname, sizeof qname, instance, 0));
	TEST_ASSERT_EQUAL(0, co_od_create(&od, 16));
	can_port_config bc = { .ifname = "vcan0", .bitrate = 1000000, .tx_queue_len = 16 };
	const char *why = NULL;
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, can_port_open(&bus, &bc, &why), why ? why : "bus port");
	line_params p = {
		.index = 0,
		.name = "sdo0",
		.can = { .ifname = "vcan0", .bitrate = 1000000 },
		.node = { .node_id = 0x7F,
			  .od = od,
			  .sdo_client_count = 2,
			  .sdo_client_timeout_ms = CLIENT_TIMEOUT_MS,
			  .sdo_server_timeout_ms = SERVER_TIMEOUT_MS },
		.mbx = { .queue_name = qname,
			 .unlink_existing = true,
			 .default_access = MBX_ACCESS_WRITE },
		.rt_cpu = -1,
		.main_wakefd = -1,
	};
	TEST_ASSERT_EQUAL_INT(0, line_create(&ln, &p));
	TEST_ASSERT_EQUAL_INT(0, line_start(ln));
	n_seen = 0;
	for (int i = 0; i < 200 && !line_is_up(ln); i++)
		usleep(10000);
	TEST_ASSERT_TRUE(line_is_up(ln));
}

void tearDown(void)
{
	line_destroy(ln);
	can_port_close(bus);
	co_od_destroy(od);
}

static uint64_t mono_ms(void)
{
	return line_now_us() / 1000u;
}

/* Wait for the next SDO request frame of any node; returns its node, or 0
 * after timeout_ms. Frames of one receive batch are kept in order. */
static uint8_t next_request(co_frame *out, unsigned timeout_ms)
{
	uint64_t until = mono_ms() + timeout_ms;
	for (;;) {
		if (n_seen) {
			*out = seen[0];
			memmove(seen, seen + 1, --n_seen * sizeof seen[0]);
			return (uint8_t)(out->id - 0x600);
		}
		if (mono_ms() >= until)
			return 0;
		can_rx_item it[8];
		int n = can_port_recv(bus, it, 8, line_now_us());
		for (int i = 0; i < n; i++) {
			const co_frame *f = &it[i].frame;
			if (!it[i].is_error && f->id > 0x600 && f->id < 0x680 && n_seen < 64)
				seen[n_seen++] = *f;
		}
		if (n <= 0)
			usleep(2000);
	}
}

/* The server of `node` answers an upload of 4 bytes, expedited. */
static void answer_upload(uint8_t node, uint16_t index, uint8_t sub, uint32_t v)
{
	co_frame f;
	co_frame_init(&f, 0x580u + node, 8);
	f.data[0] = 0x43;
	co_put_le16(&f.data[1], index);
	f.data[3] = sub;
	co_put_le32(&f.data[4], v);
	TEST_ASSERT_EQUAL_INT(0, can_port_send(bus, &f, line_now_us()));
}

static cogw *open_client(void)
{
	cogw *h = NULL;
	cogw_options o = { .instance = instance, .timeout_ms = 10000 };
	TEST_ASSERT_EQUAL_INT(0, cogw_open_opts(&h, &o));
	return h;
}

static uint64_t start_read(cogw *h, uint8_t node, uint16_t index)
{
	mbx_sdo_req s = { .node = node, .index = index, .sub = 0 };
	uint64_t corr = 0;
	TEST_ASSERT_EQUAL_INT(0, cogw_send_async(h, 0, MBX_CMD_SDO_UPLOAD, &s, sizeof s, &corr));
	return corr;
}

/* The answer to corr (events are skipped). */
static void wait_answer(cogw *h, uint64_t corr, cogw_msg *m)
{
	for (int i = 0; i < 50; i++) {
		int rc = cogw_recv(h, m, 10000);
		TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, "no answer");
		if (m->kind == MBX_KIND_RESPONSE && m->corr == corr)
			return;
		cogw_msg_release(m);
	}
	TEST_FAIL_MESSAGE("answer never came");
}

static void test_read_answered_with_the_servers_data(void)
{
	cogw *h = open_client();
	uint64_t corr = start_read(h, 5, 0x1018);
	co_frame f;
	TEST_ASSERT_EQUAL_UINT8(5, next_request(&f, 5000));
	TEST_ASSERT_EQUAL_HEX8(0x40, f.data[0]); /* initiate upload */
	TEST_ASSERT_EQUAL_HEX16(0x1018, co_get_le16(&f.data[1]));
	answer_upload(5, 0x1018, 0, 0x12345678);
	cogw_msg m;
	wait_answer(h, corr, &m);
	TEST_ASSERT_EQUAL_INT(0, m.status);
	TEST_ASSERT_EQUAL_UINT(4, m.len);
	TEST_ASSERT_EQUAL_HEX32(0x12345678, co_get_le32(m.data));
	cogw_msg_release(&m);
	cogw_close(h);
}

static void test_silent_node_does_not_hold_back_another(void)
{
	cogw *h = open_client();
	uint64_t c5 = start_read(h, 5, 0x1000);
	uint64_t c6 = start_read(h, 6, 0x1000);
	co_frame f;
	uint8_t a = next_request(&f, 5000), b = next_request(&f, 5000);
	/* both on the wire before anybody answered */
	TEST_ASSERT_EQUAL_UINT(5 + 6, a + b);
	answer_upload(6, 0x1000, 0, 0x00020192);
	cogw_msg m;
	wait_answer(h, c6, &m);
	TEST_ASSERT_EQUAL_INT(0, m.status);
	cogw_msg_release(&m);
	wait_answer(h, c5, &m); /* node 5 stays silent: its own timeout */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_TIMEOUT, m.abort);
	cogw_msg_release(&m);
	cogw_close(h);
}

static void test_default_timeout_is_the_clients(void)
{
	cogw *h = open_client();
	uint64_t t0 = mono_ms();
	uint64_t corr = start_read(h, 9, 0x1000); /* timeout_ms 0: the line's default */
	cogw_msg m;
	wait_answer(h, corr, &m);
	uint64_t took = mono_ms() - t0;
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_TIMEOUT, m.abort);
	cogw_msg_release(&m);
	char why[96];
	snprintf(why, sizeof why, "timed out after %llu ms", (unsigned long long)took);
	TEST_ASSERT_TRUE_MESSAGE(took >= CLIENT_TIMEOUT_MS - 10, why);
	TEST_ASSERT_TRUE_MESSAGE(took < SERVER_TIMEOUT_MS / 2, why); /* not the server's 5 s */
	cogw_close(h);
}

static void test_client_gone_cancels_exactly_its_transfer(void)
{
	cogw *a = open_client(), *b = open_client();
	mbx_sdo_req slow = { .node = 5, .index = 0x1000, .timeout_ms = 4000 };
	mbx_sdo_req other = { .node = 6, .index = 0x1000, .timeout_ms = 4000 };
	uint64_t ca = 0, cb = 0;
	TEST_ASSERT_EQUAL_INT(0,
			      cogw_send_async(a, 0, MBX_CMD_SDO_UPLOAD, &slow, sizeof slow, &ca));
	TEST_ASSERT_EQUAL_INT(0,
			      cogw_send_async(b, 0, MBX_CMD_SDO_UPLOAD, &other, sizeof other, &cb));
	co_frame f;
	uint8_t n1 = next_request(&f, 5000), n2 = next_request(&f, 5000);
	TEST_ASSERT_EQUAL_UINT(5 + 6, n1 + n2);
	cogw_close(a); /* A goes away: its transfer to node 5 is aborted */
	TEST_ASSERT_EQUAL_UINT8(5, next_request(&f, 3000));
	TEST_ASSERT_EQUAL_HEX8(0x80, f.data[0]);
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_GENERAL, co_get_le32(&f.data[4]));
	/* nothing for node 6: B's transfer goes on and completes */
	TEST_ASSERT_EQUAL_UINT8(0, next_request(&f, 300));
	answer_upload(6, 0x1000, 0, 0xCAFE);
	cogw_msg m;
	wait_answer(b, cb, &m);
	TEST_ASSERT_EQUAL_INT(0, m.status);
	TEST_ASSERT_EQUAL_HEX32(0xCAFE, co_get_le32(m.data));
	cogw_msg_release(&m);
	cogw_close(b);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_read_answered_with_the_servers_data);
	RUN_TEST(test_silent_node_does_not_hold_back_another);
	RUN_TEST(test_default_timeout_is_the_clients);
	RUN_TEST(test_client_gone_cancels_exactly_its_transfer);
	return UNITY_END();
}
