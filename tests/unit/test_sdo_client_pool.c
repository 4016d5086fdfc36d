/* SPDX-License-Identifier: MIT */
/*
 * SDO client channels as a pool (core/sdo_client.h): a request borrows any
 * free channel, a busy channel never holds back a request another channel
 * could serve, requests to one node stay serialised, no_wait refuses at
 * once, the pool FIFO is bounded; the per-request confirmation comes
 * exactly once and never inside the submitting call; cancel by tag; the
 * default per-frame timeout is the client's own setting; a relayed
 * request (CiA 302-7 routing) talks only through its relay.
 */
#include <errno.h>
#include <string.h>

#include "unity.h"

#include "core/co.h"
#include "core/sdo_client.h"
#include "tests/unit/support/test_bus.h"

static tb_bus bus;
static tb_port *cli;
static uint8_t buf[64];

/* What the confirmations told, in order. */
static struct {
	unsigned n;
	co_ev_sdo_cli con[32];
	bool in_submit; /* set around every submit in this file */
	unsigned during_submit;
} seen;

static void on_con(void *arg, const co_ev_sdo_cli *con)
{
	TEST_ASSERT_EQUAL_PTR(&seen, arg);
	if (seen.in_submit)
		seen.during_submit++;
	if (seen.n < 32)
		seen.con[seen.n] = *con;
	seen.n++;
}

static void make_client(uint8_t channels, uint16_t pool_len, uint32_t timeout_ms)
{
	co_node_config cfg = { .node_id = 1,
			       .sdo_client_count = channels,
			       .sdo_client_queue_len = 2,
			       .sdo_client_pool_len = pool_len,
			       .sdo_client_timeout_ms = timeout_ms,
			       /* must not be what the client uses */
			       .sdo_server_timeout_ms = 5000 };
	co_od *od;

	TEST_ASSERT_EQUAL(0, co_od_create(&od, 8));
	cli = tb_add_node(&bus, &cfg, od);
	TEST_ASSERT_NOT_NULL(cli);
}

void setUp(void)
{
	tb_init(&bus);
	memset(&seen, 0, sizeof(seen));
	memset(buf, 0, sizeof(buf));
	make_client(2, 4, 0);
}

void tearDown(void)
{
	tb_fini(&bus);
}

static sdo_client_req read_req(uint8_t node, uint64_t tag)
{
	return (sdo_client_req){ .upload = true,
				 .node_id = node,
				 .index = 0x1000,
				 .buf = buf,
				 .cap = sizeof(buf),
				 .timeout_ms = 500,
				 .tag = tag,
				 .con = on_con,
				 .con_arg = &seen };
}

static int pool_read(uint8_t node, uint64_t tag, bool no_wait)
{
	sdo_client_req r = read_req(node, tag);
	int rc;

	r.no_wait = no_wait;
	seen.in_submit = true;
	rc = sdo_client_pool_submit(cli->node, &r, bus.now);
	seen.in_submit = false;
	return rc;
}

/* Number of upload initiate requests sent to a node's server so far. */
static size_t requests_to(uint8_t node)
{
	return tb_count_from_id(&bus, 0, 0x600u + node, 0);
}

/* The server of `node` answers the upload with an expedited 4-byte value. */
static void answer(uint8_t node)
{
	tb_send_hex(&bus, 0x580u + node, "43 00 10 00 92 01 02 00");
}

static void test_busy_channel_does_not_block_another_node(void)
{
	TEST_ASSERT_EQUAL(0, pool_read(5, 1, false));
	TEST_ASSERT_EQUAL(0, pool_read(6, 2, false));
	/* Both on the wire at once: node 6 took the second channel. */
	TEST_ASSERT_EQUAL(1, requests_to(5));
	TEST_ASSERT_EQUAL(1, requests_to(6));
	TEST_ASSERT_EQUAL(1, sdo_client_pending(cli->node, 0));
	TEST_ASSERT_EQUAL(1, sdo_client_pending(cli->node, 1));

	/* A third node waits for a channel ... */
	TEST_ASSERT_EQUAL(0, pool_read(7, 3, false));
	TEST_ASSERT_EQUAL(0, requests_to(7));
	TEST_ASSERT_EQUAL(1, sdo_client_pool_waiting(cli->node));
	/* ... and takes whichever frees first, although node 5 stays silent. */
	answer(6);
	TEST_ASSERT_EQUAL(1, seen.n);
	TEST_ASSERT_EQUAL_UINT64(2, seen.con[0].tag);
	TEST_ASSERT_EQUAL_UINT8(1, seen.con[0].channel);
	TEST_ASSERT_EQUAL(1, requests_to(7));
	TEST_ASSERT_EQUAL(0, sdo_client_pool_waiting(cli->node));
	answer(7);
	TEST_ASSERT_EQUAL(2, seen.n);
	TEST_ASSERT_EQUAL_UINT64(3, seen.con[1].tag);
	TEST_ASSERT_EQUAL_UINT8(1, seen.con[1].channel);
	TEST_ASSERT_EQUAL_HEX32(0, seen.con[1].abort);
	TEST_ASSERT_EQUAL_UINT32(4, seen.con[1].size);
	TEST_ASSERT_EQUAL_PTR(buf, seen.con[1].data);
	TEST_ASSERT_EQUAL_HEX8(0x92, buf[0]);
	TEST_ASSERT_EQUAL(0, seen.during_submit);
}

static void test_same_node_serialised_others_pass(void)
{
	TEST_ASSERT_EQUAL(0, pool_read(5, 1, false));
	TEST_ASSERT_EQUAL(0, pool_read(5, 2, false));
	TEST_ASSERT_EQUAL(0, pool_read(6, 3, false));
	/* The second request to node 5 waits although a channel is free;
	 * node 6 behind it is not held back. */
	TEST_ASSERT_EQUAL(1, requests_to(5));
	TEST_ASSERT_EQUAL(1, requests_to(6));
	TEST_ASSERT_EQUAL(1, sdo_client_pool_waiting(cli->node));
	answer(5);
	TEST_ASSERT_EQUAL_UINT64(1, seen.con[0].tag);
	TEST_ASSERT_EQUAL(2, requests_to(5)); /* the second one now */
	answer(5);
	answer(6);
	TEST_ASSERT_EQUAL(3, seen.n);
	TEST_ASSERT_EQUAL_UINT64(2, seen.con[1].tag);
	TEST_ASSERT_EQUAL_UINT64(3, seen.con[2].tag);
	TEST_ASSERT_EQUAL(0, sdo_client_pool_waiting(cli->node));
}

static void test_no_wait_refused_at_once(void)
{
	TEST_ASSERT_EQUAL(0, pool_read(5, 1, true)); /* a channel is free */
	/* Same target busy: it would have to wait. */
	TEST_ASSERT_EQUAL(-EBUSY, pool_read(5, 2, true));
	TEST_ASSERT_EQUAL(0, pool_read(6, 3, true));
	/* No channel free. */
	TEST_ASSERT_EQUAL(-EBUSY, pool_read(7, 4, true));
	TEST_ASSERT_EQUAL(0, requests_to(7));
	TEST_ASSERT_EQUAL(0, sdo_client_pool_waiting(cli->node));
	/* A refused request is not accepted: it never confirms. */
	tb_advance(&bus, 2000000);
	TEST_ASSERT_EQUAL(2, seen.n); /* the two accepted ones timed out */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_TIMEOUT, seen.con[0].abort);
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_TIMEOUT, seen.con[1].abort);
	/* What callers answer for a refusal. */
	TEST_ASSERT_EQUAL_HEX32(0x060A0023, SDO_AB_NO_RESOURCE);
}

static void test_pool_fifo_is_bounded(void)
{
	TEST_ASSERT_EQUAL(0, pool_read(5, 1, false));
	TEST_ASSERT_EQUAL(0, pool_read(6, 2, false));
	for (uint64_t t = 3; t < 3 + 4; t++)
		TEST_ASSERT_EQUAL(0, pool_read((uint8_t)(7 + t), t, false));
	TEST_ASSERT_EQUAL(4, sdo_client_pool_waiting(cli->node));
	TEST_ASSERT_EQUAL(-ENOSPC, pool_read(20, 9, false));
	/* A bad request is refused before any bound. */
	sdo_client_req bad = read_req(0, 10);
	TEST_ASSERT_EQUAL(-EINVAL, sdo_client_pool_submit(cli->node, &bad, bus.now));
}

static void test_confirmation_once_per_request(void)
{
	/* success, remote abort, timeout, cancelled while waiting, cancelled
	 * while running: one confirmation each, one event each. */
	TEST_ASSERT_EQUAL(0, pool_read(5, 1, false));
	TEST_ASSERT_EQUAL(0, pool_read(6, 2, false));
	TEST_ASSERT_EQUAL(0, pool_read(7, 3, false));        /* waits */
	TEST_ASSERT_EQUAL(0, pool_read(8, 4, false));        /* waits */
	answer(5);                                           /* 1 ok, 3 starts */
	tb_send_hex(&bus, 0x586, "80 00 10 00 00 00 02 06"); /* 2 aborted, 4 starts */
	TEST_ASSERT_EQUAL(0, sdo_client_cancel_tag(cli->node, 4, SDO_AB_GENERAL, bus.now));
	tb_advance(&bus, 500000); /* 3 times out */
	tb_advance(&bus, 2000000);
	TEST_ASSERT_EQUAL(4, seen.n);
	TEST_ASSERT_EQUAL(4, tb_event_count(cli, CO_EV_SDO_CLIENT_DONE));
	TEST_ASSERT_EQUAL_UINT64(1, seen.con[0].tag);
	TEST_ASSERT_EQUAL_HEX32(0, seen.con[0].abort);
	TEST_ASSERT_EQUAL_UINT64(2, seen.con[1].tag);
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_NO_OBJ, seen.con[1].abort);
	TEST_ASSERT_EQUAL_UINT64(4, seen.con[2].tag);
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_GENERAL, seen.con[2].abort);
	TEST_ASSERT_EQUAL_UINT64(3, seen.con[3].tag);
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_TIMEOUT, seen.con[3].abort);
	TEST_ASSERT_EQUAL(0, seen.during_submit);
	/* The event carries what con carried. */
	TEST_ASSERT_EQUAL_UINT64(3, tb_last_event(cli, CO_EV_SDO_CLIENT_DONE)->u.sdo_cli.tag);
}

static int failing_source(void *ctx, uint32_t offset, uint8_t *out, uint32_t len)
{
	(void)ctx;
	(void)offset;
	(void)out;
	(void)len;
	return -EIO;
}

static void test_start_failure_confirmed_at_next_tick(void)
{
	sdo_client_req r = { .node_id = 5,
			     .index = 0x2000,
			     .size = 2,
			     .src = failing_source,
			     .tag = 7,
			     .con = on_con,
			     .con_arg = &seen };

	seen.in_submit = true;
	TEST_ASSERT_EQUAL(0, sdo_client_pool_submit(cli->node, &r, bus.now));
	seen.in_submit = false;
	TEST_ASSERT_EQUAL(0, seen.n);
	TEST_ASSERT_EQUAL(0, tb_event_count(cli, CO_EV_SDO_CLIENT_DONE));
	TEST_ASSERT_TRUE(co_node_next_deadline_us(cli->node) <= bus.now); /* due now */
	co_node_tick(cli->node, bus.now);
	TEST_ASSERT_EQUAL(1, seen.n);
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_STORE, seen.con[0].abort);
	TEST_ASSERT_EQUAL(0, requests_to(5)); /* nothing went out */
	co_node_tick(cli->node, bus.now + 1000000);
	TEST_ASSERT_EQUAL(1, seen.n);
}

static void test_cancel_by_tag_anywhere(void)
{
	static const uint8_t d[1] = { 1 };

	TEST_ASSERT_EQUAL(0, pool_read(5, 1, false)); /* running, channel 0 */
	/* queued on channel 1 by name, behind a running one */
	TEST_ASSERT_EQUAL(0, sdo_client_write(cli->node, 1, 6, 0x2000, 1, d, 1, 0, 2, bus.now));
	TEST_ASSERT_EQUAL(0, sdo_client_write(cli->node, 1, 6, 0x2000, 2, d, 1, 0, 3, bus.now));
	TEST_ASSERT_EQUAL(0, pool_read(7, 4, false)); /* waits in the pool */

	TEST_ASSERT_EQUAL(0, sdo_client_cancel_tag(cli->node, 4, SDO_AB_GENERAL, bus.now));
	TEST_ASSERT_EQUAL_UINT64(4, seen.con[0].tag);
	TEST_ASSERT_EQUAL_UINT8(SDO_CLIENT_NO_CHANNEL, seen.con[0].channel);
	TEST_ASSERT_EQUAL(0, sdo_client_pool_waiting(cli->node));

	TEST_ASSERT_EQUAL(0, sdo_client_cancel_tag(cli->node, 3, SDO_AB_GENERAL, bus.now));
	TEST_ASSERT_EQUAL_UINT64(3, tb_last_event(cli, CO_EV_SDO_CLIENT_DONE)->u.sdo_cli.tag);
	TEST_ASSERT_EQUAL(1, sdo_client_pending(cli->node, 1));

	TEST_ASSERT_EQUAL(0, sdo_client_cancel_tag(cli->node, 1, SDO_AB_GENERAL, bus.now));
	TB_ASSERT_LAST(&bus, 0, 0x605, "80 00 10 00 00 00 00 08");
	TEST_ASSERT_EQUAL_UINT64(1, seen.con[1].tag);
	TEST_ASSERT_EQUAL_UINT8(0, seen.con[1].channel);
	TEST_ASSERT_EQUAL(-ENOENT, sdo_client_cancel_tag(cli->node, 1, SDO_AB_GENERAL, bus.now));
	TEST_ASSERT_EQUAL(-ENOENT, sdo_client_cancel_tag(cli->node, 99, SDO_AB_GENERAL, bus.now));
	TEST_ASSERT_EQUAL(2, seen.n);
}

/* A confirmation may submit the next request (a manager's chain). */
static void chain_con(void *arg, const co_ev_sdo_cli *con)
{
	(void)arg;
	on_con(&seen, con);
	if (con->tag == 1) {
		sdo_client_req r = read_req(5, 2);
		TEST_ASSERT_EQUAL(0, sdo_client_pool_submit(cli->node, &r, bus.now));
	}
}

static void test_confirmation_may_submit(void)
{
	sdo_client_req r = read_req(5, 1);

	r.con = chain_con;
	TEST_ASSERT_EQUAL(0, sdo_client_pool_submit(cli->node, &r, bus.now));
	answer(5);
	TEST_ASSERT_EQUAL(2, requests_to(5));
	answer(5);
	TEST_ASSERT_EQUAL(2, seen.n);
	TEST_ASSERT_EQUAL_UINT64(2, seen.con[1].tag);
}

static void test_default_timeout_is_the_clients_own(void)
{
	sdo_client_req r;

	tb_fini(&bus);
	tb_init(&bus);
	make_client(1, 0, 300); /* server setting stays 5000 */
	r = read_req(5, 1);
	r.timeout_ms = 0;
	TEST_ASSERT_EQUAL(0, sdo_client_pool_submit(cli->node, &r, bus.now));
	tb_advance(&bus, 299999);
	TEST_ASSERT_EQUAL(0, seen.n);
	tb_advance(&bus, 1);
	TEST_ASSERT_EQUAL(1, seen.n);
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_TIMEOUT, seen.con[0].abort);
}

static void test_without_client_channels(void)
{
	sdo_client_req r = read_req(5, 1);
	co_node_config cfg = { .node_id = 2 };
	co_od *od;

	TEST_ASSERT_EQUAL(0, co_od_create(&od, 8));
	tb_port *p = tb_add_node(&bus, &cfg, od);
	TEST_ASSERT_EQUAL(-EINVAL, sdo_client_pool_submit(p->node, &r, bus.now));
	TEST_ASSERT_EQUAL(-ENOENT, sdo_client_cancel_tag(p->node, 1, SDO_AB_GENERAL, bus.now));
	TEST_ASSERT_EQUAL(0, sdo_client_pool_waiting(p->node));
}

/* ---- relay lease (CiA 302-7) ------------------------------------------------ */

static struct {
	unsigned n;
	uint8_t last[8];
} raw;

static void on_raw(void *arg, const uint8_t d[8], uint64_t now_us)
{
	(void)now_us;
	TEST_ASSERT_EQUAL_PTR(&raw, arg);
	raw.n++;
	memcpy(raw.last, d, 8);
}

static void test_lease_relays_raw_frames_and_holds_the_target(void)
{
	uint8_t d[8] = { 0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0 };
	int ch;

	memset(&raw, 0, sizeof(raw));
	ch = sdo_client_lease(cli->node, 5, 0, 0, on_raw, &raw, bus.now);
	TEST_ASSERT_TRUE(ch >= 0);
	TEST_ASSERT_EQUAL(1, sdo_client_pending(cli->node, (uint8_t)ch));
	TEST_ASSERT_EQUAL(0, sdo_client_lease_send(cli->node, (uint8_t)ch, d));
	TB_ASSERT_LAST(&bus, cli->idx, 0x605, "40 00 10 00 00 00 00 00");
	tb_send_hex(&bus, 0x585, "43 00 10 00 91 01 0F 00");
	TEST_ASSERT_EQUAL(1, raw.n);
	TEST_ASSERT_EQUAL_HEX8(0x43, raw.last[0]);
	/* the same server again: busy; a pool request to it waits */
	TEST_ASSERT_EQUAL(-EALREADY, sdo_client_lease(cli->node, 5, 0, 0, on_raw, &raw, bus.now));
	TEST_ASSERT_EQUAL(0, pool_read(5, 1, false));
	TEST_ASSERT_EQUAL(1, sdo_client_pool_waiting(cli->node));
	/* no timeout on a lease */
	tb_advance(&bus, 10000000);
	TEST_ASSERT_EQUAL(0, seen.n);
	/* a second server takes the other channel; then none is free */
	TEST_ASSERT_TRUE(sdo_client_lease(cli->node, 6, 0, 0, on_raw, &raw, bus.now) >= 0);
	TEST_ASSERT_EQUAL(-EBUSY, sdo_client_lease(cli->node, 7, 0, 0, on_raw, &raw, bus.now));
	TEST_ASSERT_EQUAL(0, sdo_client_lease_end(cli->node, (uint8_t)ch, bus.now));
	TEST_ASSERT_EQUAL(-ENOENT, sdo_client_lease_end(cli->node, (uint8_t)ch, bus.now));
	TEST_ASSERT_EQUAL(-ENOENT, sdo_client_lease_send(cli->node, (uint8_t)ch, d));
	/* the waiting request started on the released channel */
	TEST_ASSERT_EQUAL(0, sdo_client_pool_waiting(cli->node));
	TB_ASSERT_LAST(&bus, cli->idx, 0x605, "40 00 10 00 00 00 00 00");
	TEST_ASSERT_EQUAL(-EINVAL, sdo_client_lease(cli->node, 0, 0, 0, on_raw, &raw, bus.now));
	TEST_ASSERT_EQUAL(-ENOENT, sdo_client_cancel_tag(cli->node, 0, SDO_AB_GENERAL, bus.now));
}

/* A transfer of ours that ended with our own abort frame may still get
 * frames from its server; a lease would relay them to the next requester
 * as answers: no lease toward that server for 100 ms. */
static void test_no_lease_while_an_aborted_transfer_settles(void)
{
	TEST_ASSERT_EQUAL(0, pool_read(5, 1, false));
	TEST_ASSERT_EQUAL(0, sdo_client_cancel_tag(cli->node, 1, SDO_AB_GENERAL, bus.now));
	TEST_ASSERT_EQUAL(-EALREADY, sdo_client_lease(cli->node, 5, 0, 0, on_raw, &raw, bus.now));
	/* another server is not concerned */
	int other = sdo_client_lease(cli->node, 6, 0, 0, on_raw, &raw, bus.now);
	TEST_ASSERT_TRUE(other >= 0);
	TEST_ASSERT_EQUAL(0, sdo_client_lease_end(cli->node, (uint8_t)other, bus.now));
	tb_advance(&bus, 99000);
	TEST_ASSERT_EQUAL(-EALREADY, sdo_client_lease(cli->node, 5, 0, 0, on_raw, &raw, bus.now));
	tb_advance(&bus, 1000);
	TEST_ASSERT_TRUE(sdo_client_lease(cli->node, 5, 0, 0, on_raw, &raw, bus.now) >= 0);
	/* a transfer the server answered leaves nothing to settle */
	TEST_ASSERT_EQUAL(0, pool_read(7, 2, false));
	answer(7);
	TEST_ASSERT_TRUE(sdo_client_lease(cli->node, 7, 0, 0, on_raw, &raw, bus.now) >= 0);
}

/* ---- relayed requests (CiA 302-7 routing: the server is elsewhere) ---- */

static struct {
	unsigned n;
	uint8_t d[16][8];
} relayed;

static void relay_to(void *ctx, const uint8_t d[8])
{
	TEST_ASSERT_EQUAL_PTR(&relayed, ctx);
	if (relayed.n < 16)
		memcpy(relayed.d[relayed.n], d, 8);
	relayed.n++;
}

static int relayed_read(uint8_t node, uint32_t target, uint64_t tag)
{
	sdo_client_req r = read_req(node, tag);
	int rc;

	memset(&relayed, 0, sizeof relayed);
	r.relay = relay_to;
	r.relay_ctx = &relayed;
	r.relay_target = target;
	seen.in_submit = true;
	rc = sdo_client_pool_submit(cli->node, &r, bus.now);
	seen.in_submit = false;
	return rc;
}

static void relay_answer(uint64_t tag, int expect)
{
	static const uint8_t d[8] = { 0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00 };

	TEST_ASSERT_EQUAL(expect, sdo_client_relay_recv(cli->node, tag, d, bus.now));
}

static void test_relayed_frames_go_to_the_relay_not_the_bus(void)
{
	TEST_ASSERT_EQUAL(0, relayed_read(5, 3u << 8 | 5, 1));
	TEST_ASSERT_EQUAL(0, requests_to(5)); /* nothing on this bus */
	TEST_ASSERT_EQUAL(1, relayed.n);
	TEST_ASSERT_EQUAL_HEX8(0x40, relayed.d[0][0]); /* upload initiate 1000h:00 */
	TEST_ASSERT_EQUAL_HEX16(0x1000, co_get_le16(&relayed.d[0][1]));
	/* node 5 of this bus is another device: its answer is not ours */
	answer(5);
	TEST_ASSERT_EQUAL(0, seen.n);
	relay_answer(1, 0);
	TEST_ASSERT_EQUAL(1, seen.n);
	TEST_ASSERT_EQUAL_HEX32(0, seen.con[0].abort);
	TEST_ASSERT_EQUAL_UINT32(4, seen.con[0].size);
	TEST_ASSERT_TRUE(seen.con[0].answered);
	TEST_ASSERT_EQUAL_HEX8(0x92, buf[0]);
	/* a late frame finds no transfer */
	relay_answer(1, -ENOENT);
	TEST_ASSERT_EQUAL(0, seen.during_submit);
}

static void test_relayed_target_serialised_apart_from_the_bus(void)
{
	TEST_ASSERT_EQUAL(0, relayed_read(5, 3u << 8 | 5, 1));
	sdo_client_req r = read_req(5, 2);
	r.relay = relay_to;
	r.relay_ctx = &relayed;
	r.relay_target = 3u << 8 | 5;
	TEST_ASSERT_EQUAL(0, sdo_client_pool_submit(cli->node, &r, bus.now));
	/* the same remote server: waits; node 5 of this bus: not held back */
	TEST_ASSERT_EQUAL(1, sdo_client_pool_waiting(cli->node));
	TEST_ASSERT_EQUAL(0, pool_read(5, 3, false));
	TEST_ASSERT_EQUAL(1, requests_to(5));
	TEST_ASSERT_EQUAL(1, relayed.n);
	relay_answer(1, 0);
	TEST_ASSERT_EQUAL(2, relayed.n); /* the second one starts now */
	relay_answer(2, 0);
	answer(5);
	TEST_ASSERT_EQUAL(3, seen.n);
}

static void test_relayed_timeout_and_cancel_end_through_the_relay(void)
{
	TEST_ASSERT_EQUAL(0, relayed_read(5, 3u << 8 | 5, 1));
	tb_advance(&bus, 600000);
	TEST_ASSERT_EQUAL(1, seen.n);
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_TIMEOUT, seen.con[0].abort);
	TEST_ASSERT_FALSE(seen.con[0].answered); /* the server never answered */
	TEST_ASSERT_EQUAL(2, relayed.n);
	TEST_ASSERT_EQUAL_HEX8(0x80, relayed.d[1][0]);
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_TIMEOUT, co_get_le32(&relayed.d[1][4]));

	TEST_ASSERT_EQUAL(0, relayed_read(6, 3u << 8 | 6, 2));
	TEST_ASSERT_EQUAL(0, sdo_client_cancel_tag(cli->node, 2, SDO_AB_NODE_UNKNOWN, bus.now));
	TEST_ASSERT_EQUAL(2, seen.n);
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_NODE_UNKNOWN, seen.con[1].abort);
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_NODE_UNKNOWN, co_get_le32(&relayed.d[1][4]));
	TEST_ASSERT_EQUAL(0, tb_count_from_id(&bus, 0, 0x606, 0));
}

/* ---- the gate: a second user lends channels and reserves servers ---- */

/* What the gate would hold for another thread, and what the core asked. */
static struct {
	bool lent[4];       /* channel lent elsewhere (reserved or leased) */
	bool own_ch[4];     /* channel the node's own requests took */
	bool reserved[128]; /* server reserved elsewhere */
	bool own_srv[128];  /* server the node's own transfers took */
	unsigned calls;     /* of the gate */
} g;

static bool test_gate(void *ctx, sdo_client_gate_op op, uint8_t arg)
{
	TEST_ASSERT_EQUAL_PTR(&g, ctx);
	g.calls++;
	switch (op) {
	case SDO_CLIENT_GATE_TAKE_CHANNEL:
		TEST_ASSERT_FALSE_MESSAGE(g.own_ch[arg], "a channel taken twice");
		if (g.lent[arg])
			return false;
		g.own_ch[arg] = true;
		return true;
	case SDO_CLIENT_GATE_FREE_CHANNEL:
		g.own_ch[arg] = g.lent[arg] = false; /* back on the board */
		return true;
	case SDO_CLIENT_GATE_TAKE_SERVER:
		TEST_ASSERT_FALSE_MESSAGE(g.own_srv[arg], "a server taken twice");
		if (g.reserved[arg])
			return false;
		g.own_srv[arg] = true;
		return true;
	case SDO_CLIENT_GATE_FREE_SERVER:
		TEST_ASSERT_TRUE_MESSAGE(g.own_srv[arg], "a server freed that was not taken");
		g.own_srv[arg] = false;
		return true;
	}
	return false;
}

static void gate_on(void)
{
	memset(&g, 0, sizeof g);
	sdo_client_set_gate(cli->node, test_gate, &g);
}

/* A channel lent elsewhere is not given to the node's own requests; the
 * lease bound on it uses exactly it, and its end lets the pool go on. */
static void test_gate_lent_channel_is_not_taken_by_own_requests(void)
{
	gate_on();
	g.lent[0] = true;
	TEST_ASSERT_EQUAL(0, pool_read(5, 1, false));
	TEST_ASSERT_EQUAL(1, requests_to(5));
	TEST_ASSERT_TRUE(g.own_ch[1]); /* node 5 went to the other channel */
	TEST_ASSERT_TRUE(g.own_srv[5]);
	/* no channel left for node 6, although channel 0 is idle */
	TEST_ASSERT_EQUAL(0, pool_read(6, 2, false));
	TEST_ASSERT_EQUAL(0, requests_to(6));
	TEST_ASSERT_EQUAL(-EBUSY, pool_read(7, 3, true));
	TEST_ASSERT_EQUAL(1, sdo_client_pool_waiting(cli->node));
	/* the lease on the lent channel toward a reserved server */
	g.reserved[9] = true;
	TEST_ASSERT_EQUAL(0, sdo_client_lease_channel(cli->node, 0, 9, on_raw, &raw, bus.now));
	TEST_ASSERT_EQUAL(-EBUSY, sdo_client_lease_channel(cli->node, 0, 9, on_raw, &raw, bus.now));
	TEST_ASSERT_EQUAL(-EBUSY, sdo_client_lease_channel(cli->node, 1, 8, on_raw, &raw, bus.now));
	/* node 5 answers: its channel goes back to the board, then node 6
	 * takes it again in the same call */
	answer(5);
	TEST_ASSERT_EQUAL(1, seen.n);
	TEST_ASSERT_EQUAL(1, requests_to(6));
	TEST_ASSERT_EQUAL_UINT8(1, seen.con[0].channel);
	TEST_ASSERT_FALSE(g.own_srv[5]);
	/* the lease ends: channel 0 is back on the board */
	TEST_ASSERT_EQUAL(0, sdo_client_lease_end(cli->node, 0, bus.now));
	TEST_ASSERT_FALSE(g.lent[0]);
	TEST_ASSERT_FALSE(g.own_ch[0]);
	answer(6);
	TEST_ASSERT_EQUAL(2, seen.n);
	TEST_ASSERT_FALSE(g.own_ch[1]);
	TEST_ASSERT_FALSE(g.own_srv[6]);
	TEST_ASSERT_EQUAL(0, seen.during_submit);
}

/* A server reserved elsewhere is busy for the node's own requests (they
 * wait, no_wait is refused); given back without a word to the node, the
 * pool takes it up from the tick. */
static void test_gate_reserved_server_waits_until_given_back(void)
{
	gate_on();
	g.reserved[5] = true;
	TEST_ASSERT_EQUAL(0, pool_read(5, 1, false));
	TEST_ASSERT_EQUAL(-EBUSY, pool_read(5, 2, true));
	TEST_ASSERT_EQUAL(0, pool_read(6, 3, false)); /* not held back */
	TEST_ASSERT_EQUAL(0, requests_to(5));
	TEST_ASSERT_EQUAL(1, requests_to(6));
	TEST_ASSERT_FALSE(g.own_srv[5]);
	TEST_ASSERT_FALSE(g.own_ch[0] && g.own_ch[1]); /* one channel stays lendable */
	/* a named channel waits for it too */
	sdo_client_req named = read_req(5, 4);
	TEST_ASSERT_EQUAL(0, sdo_client_submit(cli->node, 0, &named, bus.now));
	TEST_ASSERT_EQUAL(0, requests_to(5));
	g.reserved[5] = false;
	tb_advance(&bus, 50000);
	TEST_ASSERT_EQUAL(0, requests_to(5));
	tb_advance(&bus, 60000); /* the retry after 100 ms */
	TEST_ASSERT_EQUAL(1, requests_to(5));
	TEST_ASSERT_TRUE(g.own_srv[5]);
	answer(5);
	answer(6);
	TEST_ASSERT_EQUAL(2, requests_to(5)); /* the other one for node 5 */
	answer(5);
	TEST_ASSERT_EQUAL(3, seen.n);
	TEST_ASSERT_FALSE(g.own_srv[5]);
	TEST_ASSERT_FALSE(g.own_ch[0] || g.own_ch[1]);
}

/* The gate's owner frees a server outside the core's calls and says so:
 * what the gate refused starts at once, not at the retry; with nothing
 * refused the kick does nothing. */
static void test_gate_kick_starts_what_was_refused_now(void)
{
	unsigned calls;

	gate_on();
	calls = g.calls;
	sdo_client_gate_kick(cli->node, bus.now);
	TEST_ASSERT_EQUAL_UINT(calls, g.calls);
	g.reserved[5] = true;
	TEST_ASSERT_EQUAL(0, pool_read(5, 1, false));
	TEST_ASSERT_EQUAL(0, requests_to(5));
	g.reserved[5] = false;
	sdo_client_gate_kick(cli->node, bus.now);
	TEST_ASSERT_EQUAL(1, requests_to(5));
	TEST_ASSERT_TRUE(g.own_srv[5]);
	answer(5);
	TEST_ASSERT_EQUAL(1, seen.n);
	TEST_ASSERT_FALSE(g.own_srv[5]);
}

/* A server whose transfer we ended with our own abort frame stays taken
 * for 100 ms (its late frames would reach a lease as answers), then the
 * gate gets it back without any other call. */
static void test_gate_server_held_while_it_settles(void)
{
	gate_on();
	TEST_ASSERT_EQUAL(0, pool_read(5, 1, false));
	tb_advance(&bus, 1000); /* ticked: the node waits for the transfer's timeout */
	TEST_ASSERT_EQUAL_UINT64(bus.now + 499000, co_node_next_deadline_us(cli->node));
	TEST_ASSERT_EQUAL(0, sdo_client_cancel_tag(cli->node, 1, SDO_AB_GENERAL, bus.now));
	TEST_ASSERT_EQUAL(1, seen.n);
	TEST_ASSERT_TRUE(g.own_srv[5]);
	TEST_ASSERT_FALSE(g.own_ch[0] || g.own_ch[1]); /* the channel is not */
	/* the node is ticked for it even with nothing else to do */
	TEST_ASSERT_EQUAL_UINT64(bus.now + 100000, co_node_next_deadline_us(cli->node));
	tb_advance(&bus, 99000);
	TEST_ASSERT_TRUE(g.own_srv[5]);
	tb_advance(&bus, 1000);
	TEST_ASSERT_FALSE(g.own_srv[5]);
	/* removing the gate forgets it: the pool is the node's alone again */
	sdo_client_set_gate(cli->node, NULL, NULL);
	g.reserved[6] = true;
	TEST_ASSERT_EQUAL(0, pool_read(6, 2, false));
	TEST_ASSERT_EQUAL(1, requests_to(6));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_busy_channel_does_not_block_another_node);
	RUN_TEST(test_same_node_serialised_others_pass);
	RUN_TEST(test_no_wait_refused_at_once);
	RUN_TEST(test_pool_fifo_is_bounded);
	RUN_TEST(test_confirmation_once_per_request);
	RUN_TEST(test_start_failure_confirmed_at_next_tick);
	RUN_TEST(test_cancel_by_tag_anywhere);
	RUN_TEST(test_confirmation_may_submit);
	RUN_TEST(test_default_timeout_is_the_clients_own);
	RUN_TEST(test_without_client_channels);
	RUN_TEST(test_lease_relays_raw_frames_and_holds_the_target);
	RUN_TEST(test_no_lease_while_an_aborted_transfer_settles);
	RUN_TEST(test_relayed_frames_go_to_the_relay_not_the_bus);
	RUN_TEST(test_relayed_target_serialised_apart_from_the_bus);
	RUN_TEST(test_relayed_timeout_and_cancel_end_through_the_relay);
	RUN_TEST(test_gate_lent_channel_is_not_taken_by_own_requests);
	RUN_TEST(test_gate_reserved_server_waits_until_given_back);
	RUN_TEST(test_gate_server_held_while_it_settles);
	RUN_TEST(test_gate_kick_starts_what_was_refused_now);
	return UNITY_END();
}
