/* SPDX-License-Identifier: MIT */
/*
 * The routed SDO session (gateway/sdo_route.h) between two in-memory buses:
 * a real core SDO client on the requester's bus and a real core SDO server
 * (the transducer fixture) on the target's bus. The session relays every
 * transfer frame by frame; every mode and size class must arrive
 * byte-exact, and every ending (refusal, abort, timeout, cancel) must
 * release the lease once and report once.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "unity.h"

#include "core/co.h"
#include "core/sdo_client.h"
#include "gateway/gw_line.h"
#include "gateway/lend.h"
#include "gateway/sdo_route.h"
#include "tests/unit/support/test_bus.h"
#include "tests/unit/support/test_od_fixture.h"

#define GW_ID 0x7F /* the gateway's node-ID on the requester's bus */
#define TGT_ID 5
#define NET 2
#define Q_LEN 4096

typedef struct fq {
	uint8_t d[Q_LEN][8];
	unsigned head, n;
} fq;

static void fq_push(fq *q, const uint8_t d[8])
{
	TEST_ASSERT_TRUE_MESSAGE(q->n < Q_LEN, "frame queue full");
	memcpy(q->d[(q->head + q->n++) % Q_LEN], d, 8);
}

static bool fq_pop(fq *q, uint8_t d[8])
{
	if (!q->n)
		return false;
	memcpy(d, q->d[q->head], 8);
	q->head = (q->head + 1) % Q_LEN;
	q->n--;
	return true;
}

static tb_bus bus_a, bus_b; /* requester's and target's lines */
static tb_port *req, *tgt;
static gw_sdo_route s;
static fq from_req, from_tgt; /* captured off the buses */
static fq to_req, to_tgt;     /* what the session sent */
static uint8_t last_to_req[8], last_to_tgt[8];
static unsigned n_to_req, n_to_tgt;
static unsigned opens, closes, dones;
static uint32_t open_answer, done_abort;
static gw_route_outcome done_outcome;
static gw_hop opened_hop;
static uint8_t *big_in, *big_out;

static void op_to_requester(void *ctx, const uint8_t d[8])
{
	(void)ctx;
	memcpy(last_to_req, d, 8);
	n_to_req++;
	fq_push(&to_req, d);
}

static void op_to_target(void *ctx, const uint8_t d[8])
{
	(void)ctx;
	memcpy(last_to_tgt, d, 8);
	n_to_tgt++;
	fq_push(&to_tgt, d);
}

static uint32_t op_open(void *ctx, const gw_hop *hop)
{
	(void)ctx;
	opens++;
	opened_hop = *hop;
	return open_answer;
}

static void op_close(void *ctx)
{
	(void)ctx;
	closes++;
}

static void op_done(void *ctx, uint32_t abort, gw_route_outcome o)
{
	(void)ctx;
	dones++;
	done_abort = abort;
	done_outcome = o;
}

static const gw_sdo_route_ops ops = {
	.to_requester = op_to_requester,
	.to_target = op_to_target,
	.open = op_open,
	.close = op_close,
	.done = op_done,
};

/* Frames the nodes send toward the gateway are taken off the bus. */
static tb_action capture_a(void *ctx, const co_frame *f, int from, uint64_t n)
{
	(void)ctx;
	(void)n;
	if (from != TB_TESTER && f->id == 0x600u + GW_ID) {
		fq_push(&from_req, f->data);
		return TB_DROP;
	}
	return TB_DELIVER;
}

static tb_action capture_b(void *ctx, const co_frame *f, int from, uint64_t n)
{
	(void)ctx;
	(void)n;
	if (from != TB_TESTER && f->id == 0x580u + TGT_ID) {
		fq_push(&from_tgt, f->data);
		return TB_DROP;
	}
	return TB_DELIVER;
}

static void inject(tb_bus *bus, uint32_t id, const uint8_t d[8])
{
	co_frame f;

	co_frame_init(&f, id, 8);
	memcpy(f.data, d, 8);
	tb_send(bus, &f);
}

/* Carry frames between the buses and the session until all is quiet. */
static void pump(void)
{
	uint8_t d[8];
	bool moved = true;

	while (moved) {
		moved = false;
		while (fq_pop(&to_req, d)) {
			inject(&bus_a, 0x580u + GW_ID, d);
			moved = true;
		}
		while (fq_pop(&to_tgt, d)) {
			inject(&bus_b, 0x600u + TGT_ID, d);
			moved = true;
		}
		while (fq_pop(&from_req, d)) {
			gw_sdo_route_requester_frame(&s, d, bus_a.now);
			moved = true;
		}
		while (fq_pop(&from_tgt, d)) {
			gw_sdo_route_target_frame(&s, d, bus_a.now);
			moved = true;
		}
	}
}

static void advance(uint64_t dt_us)
{
	tb_advance(&bus_a, dt_us);
	tb_advance(&bus_b, dt_us);
	gw_sdo_route_tick(&s, bus_a.now);
	pump();
}

void setUp(void)
{
	co_node_config rcfg = { .node_id = 1, .sdo_client_count = 1 };
	co_node_config tcfg = { .node_id = TGT_ID };
	co_od *rod;

	memset(&from_req, 0, sizeof(from_req));
	memset(&from_tgt, 0, sizeof(from_tgt));
	memset(&to_req, 0, sizeof(to_req));
	memset(&to_tgt, 0, sizeof(to_tgt));
	n_to_req = n_to_tgt = opens = closes = dones = 0;
	open_answer = done_abort = 0;
	tb_init(&bus_a);
	tb_init(&bus_b);
	bus_a.log_on = bus_b.log_on = false;
	TEST_ASSERT_EQUAL(0, co_od_create(&rod, 16));
	req = tb_add_node(&bus_a, &rcfg, rod);
	tgt = tb_add_node(&bus_b, &tcfg, fx_od_new());
	TEST_ASSERT_NOT_NULL(req);
	TEST_ASSERT_NOT_NULL(tgt);
	bus_a.filter = capture_a;
	bus_b.filter = capture_b;
	gw_sdo_route_init(&s, &ops, NULL);
	big_in = malloc(FX_DOMAIN_MAX);
	big_out = malloc(FX_DOMAIN_MAX);
	for (uint32_t i = 0; i < FX_DOMAIN_MAX; i++)
		big_in[i] = (uint8_t)(i * 13u + (i >> 8));
}

void tearDown(void)
{
	tb_fini(&bus_a);
	tb_fini(&bus_b);
	free(big_in);
	free(big_out);
}

static void hex_eq(const char *want, const uint8_t d[8])
{
	char got[32];

	for (int i = 0; i < 8; i++)
		snprintf(&got[i * 3], 4, i < 7 ? "%02X " : "%02X", d[i]);
	TEST_ASSERT_EQUAL_STRING(want, got);
}

/* Network indication for (NET, TGT_ID), lease granted: confirmed in the
 * same call, no answer of the target line waited for. */
static void indicate(void)
{
	gw_hop hop = { .line = 1, .node = TGT_ID };

	TEST_ASSERT_EQUAL(0, gw_sdo_route_start(&s, (gw_netind){ NET, TGT_ID }, 0, &hop, 1000, 1000,
						bus_a.now));
	TEST_ASSERT_EQUAL(GW_SR_WAIT_INIT, gw_sdo_route_state_of(&s));
	hex_eq("E0 02 00 05 00 00 00 00", last_to_req);
	pump();
}

static const co_event *client_run(const sdo_client_req *r)
{
	size_t before = tb_event_count(req, CO_EV_SDO_CLIENT_DONE);

	TEST_ASSERT_EQUAL(0, sdo_client_submit(req->node, 0, r, bus_a.now));
	for (int i = 0; i < 20000 && tb_event_count(req, CO_EV_SDO_CLIENT_DONE) == before; i++) {
		pump();
		if (tb_event_count(req, CO_EV_SDO_CLIENT_DONE) == before)
			advance(1000);
	}
	TEST_ASSERT_EQUAL_MESSAGE(before + 1, tb_event_count(req, CO_EV_SDO_CLIENT_DONE),
				  "no completion");
	pump();
	return tb_last_event(req, CO_EV_SDO_CLIENT_DONE);
}

static void routed_roundtrip(uint32_t size, uint8_t mode)
{
	char msg[80];
	co_od_entry *e = co_od_find(tgt->od, FX_IDX_DOMAIN, 0);
	unsigned d0 = dones;
	const co_event *ev;
	sdo_client_req dn = { .node_id = GW_ID,
			      .index = FX_IDX_DOMAIN,
			      .mode = mode,
			      .data = big_in,
			      .size = size,
			      .tag = 1 };
	sdo_client_req up = { .upload = true,
			      .node_id = GW_ID,
			      .index = FX_IDX_DOMAIN,
			      .mode = mode,
			      .buf = big_out,
			      .cap = FX_DOMAIN_MAX,
			      .size = size,
			      .tag = 2 };

	snprintf(msg, sizeof(msg), "size %u mode %s", size, sdo_mode_to_string((sdo_mode)mode));
	indicate();
	ev = client_run(&dn);
	TEST_ASSERT_EQUAL_HEX32_MESSAGE(0, ev->u.sdo_cli.abort, msg);
	TEST_ASSERT_EQUAL_UINT32_MESSAGE(size, e->size, msg);
	TEST_ASSERT_EQUAL_MEMORY_MESSAGE(big_in, e->data, size, msg);
	TEST_ASSERT_EQUAL_MESSAGE(d0 + 1, dones, msg);
	TEST_ASSERT_EQUAL_HEX32_MESSAGE(0, done_abort, msg);
	TEST_ASSERT_EQUAL_MESSAGE(GW_OUT_ROUTED, done_outcome, msg);
	TEST_ASSERT_FALSE_MESSAGE(gw_sdo_route_busy(&s), msg);

	memset(big_out, 0, size);
	indicate();
	ev = client_run(&up);
	TEST_ASSERT_EQUAL_HEX32_MESSAGE(0, ev->u.sdo_cli.abort, msg);
	TEST_ASSERT_EQUAL_UINT32_MESSAGE(size, ev->u.sdo_cli.size, msg);
	TEST_ASSERT_EQUAL_MEMORY_MESSAGE(big_in, big_out, size, msg);
	TEST_ASSERT_EQUAL_MESSAGE(d0 + 2, dones, msg);
	TEST_ASSERT_EQUAL_MESSAGE(GW_OUT_ROUTED, done_outcome, msg);
	TEST_ASSERT_EQUAL_MESSAGE(opens, closes, msg);
}

static void test_every_mode_and_size_arrives_byte_exact(void)
{
	static const uint32_t sizes[] = { 1, 3, 4, 5, 7, 8, 14, 100, 889, 890, 4096, 100000 };
	static const uint8_t modes[] = { SDO_MODE_EXPEDITED, SDO_MODE_SEGMENTED, SDO_MODE_BLOCK };

	for (size_t m = 0; m < sizeof(modes); m++)
		for (size_t i = 0; i < sizeof(sizes) / sizeof(sizes[0]); i++)
			routed_roundtrip(sizes[i], modes[m]);
}

static void test_expedited_frames_are_relayed_unchanged(void)
{
	uint8_t init[8] = { 0x2B, 0x17, 0x10, 0x00, 0xE8, 0x03, 0, 0 };

	indicate();
	gw_sdo_route_requester_frame(&s, init, bus_a.now);
	TEST_ASSERT_EQUAL(GW_SR_DN_INIT_RESP, gw_sdo_route_state_of(&s));
	TEST_ASSERT_EQUAL_MEMORY(init, last_to_tgt, 8);
	pump();
	hex_eq("60 17 10 00 00 00 00 00", last_to_req);
	TEST_ASSERT_EQUAL(1, dones);
	TEST_ASSERT_EQUAL(GW_OUT_ROUTED, done_outcome);
}

/* What a lease sends across to the requester itself (the one answer to a
 * request of a normal transfer) must be exactly what the session would
 * forward unchanged in that state: for every first byte of the answer,
 * after each kind of request, gw_sdo_route_answer_passes agrees with the
 * session; never for a block transfer. */
static void test_answers_sent_across_are_those_the_session_forwards(void)
{
	static const struct {
		uint8_t before[2][8]; /* requester, target frames that lead there */
		unsigned n_before;
		uint8_t asked[8];
		bool normal;
	} cases[] = {
		{ .asked = { 0x23, 0x17, 0x10, 0, 1, 2, 3, 4 }, .normal = true },
		{ .asked = { 0x21, 0x17, 0x10, 0, 20, 0, 0, 0 }, .normal = true },
		{ .asked = { 0x40, 0x17, 0x10, 0 }, .normal = true },
		{ .before = { { 0x21, 0x17, 0x10, 0, 20, 0, 0, 0 }, { 0x60, 0x17, 0x10, 0 } },
		  .n_before = 2,
		  .asked = { 0x00, 1, 2, 3, 4, 5, 6, 7 },
		  .normal = true },
		{ .before = { { 0x40, 0x17, 0x10, 0 }, { 0x41, 0x17, 0x10, 0, 20, 0, 0, 0 } },
		  .n_before = 2,
		  .asked = { 0x60 },
		  .normal = true },
		{ .asked = { 0xA4, 0x17, 0x10, 0, 127, 0, 0, 0 } }, /* block upload */
		{ .asked = { 0xC2, 0x17, 0x10, 0, 20, 0, 0, 0 } },  /* block download */
	};
	gw_hop hop = { .line = 1, .node = TGT_ID };

	for (size_t c = 0; c < sizeof(cases) / sizeof(cases[0]); c++) {
		for (unsigned b0 = 0; b0 < 256; b0++) {
			uint8_t answer[8] = { (uint8_t)b0, 0x17, 0x10, 0, 9, 8, 7, 6 };
			unsigned sent_before;
			bool forwarded, passes;
			char why[48];

			memset(&to_req, 0, sizeof(to_req));
			memset(&to_tgt, 0, sizeof(to_tgt));
			TEST_ASSERT_EQUAL(0, gw_sdo_route_start(&s, (gw_netind){ NET, TGT_ID }, 0,
								&hop, 1000, 1000, 0));
			if (cases[c].n_before) {
				gw_sdo_route_requester_frame(&s, cases[c].before[0], 0);
				gw_sdo_route_target_frame(&s, cases[c].before[1], 0);
			}
			gw_sdo_route_requester_frame(&s, cases[c].asked, 0);
			TEST_ASSERT_TRUE(gw_sdo_route_busy(&s));
			sent_before = n_to_req;
			gw_sdo_route_target_frame(&s, answer, 0);
			forwarded = n_to_req == sent_before + 1 &&
				    memcmp(last_to_req, answer, 8) == 0;
			passes = gw_sdo_route_answer_passes(cases[c].asked[0], answer);
			snprintf(why, sizeof why, "case %zu, answer %02X", c, b0);
			if (cases[c].normal)
				TEST_ASSERT_EQUAL_MESSAGE(forwarded, passes, why);
			else
				TEST_ASSERT_FALSE_MESSAGE(passes, why);
			gw_sdo_route_cancel(&s, SDO_AB_GENERAL, 0);
		}
	}
}

static void test_refusals_come_at_once(void)
{
	gw_hop hop = { .line = 1, .node = TGT_ID };

	/* the caller's route lookup refused: no lease asked */
	TEST_ASSERT_EQUAL(
		0, gw_sdo_route_start(&s, (gw_netind){ 9, 3 }, GW_AB_NET_UNKNOWN, NULL, 0, 0, 0));
	hex_eq("80 09 00 03 01 00 00 0A", last_to_req);
	TEST_ASSERT_EQUAL(0, opens);
	TEST_ASSERT_EQUAL(1, dones);
	TEST_ASSERT_EQUAL(GW_OUT_REFUSED, done_outcome);
	TEST_ASSERT_FALSE(gw_sdo_route_busy(&s));

	/* the hand-off to the target line is full */
	open_answer = GW_AB_ROUTE_BUSY;
	gw_sdo_route_start(&s, (gw_netind){ NET, TGT_ID }, 0, &hop, 0, 0, 0);
	hex_eq("80 02 00 05 03 00 00 0A", last_to_req);
	TEST_ASSERT_EQUAL(0, closes);
	TEST_ASSERT_EQUAL(2, dones);

	/* the target line has no free client, or is down: in the same call */
	open_answer = GW_AB_NO_CLIENT;
	gw_sdo_route_start(&s, (gw_netind){ NET, TGT_ID }, 0, &hop, 0, 0, 0);
	hex_eq("80 02 00 05 23 00 0A 06", last_to_req);
	open_answer = GW_AB_NO_ANSWER;
	gw_sdo_route_start(&s, (gw_netind){ NET, TGT_ID }, 0, &hop, 0, 0, 0);
	hex_eq("80 02 00 05 02 00 00 0A", last_to_req);
	TEST_ASSERT_EQUAL(0, closes); /* nothing was granted */
	TEST_ASSERT_EQUAL(4, dones);
	TEST_ASSERT_EQUAL(0, n_to_tgt);
	open_answer = 0;
	TEST_ASSERT_EQUAL(0, gw_sdo_route_start(&s, (gw_netind){ NET, TGT_ID }, 0, &hop, 0, 0, 0));
	TEST_ASSERT_EQUAL(-EBUSY,
			  gw_sdo_route_start(&s, (gw_netind){ NET, TGT_ID }, 0, &hop, 0, 0, 0));
}

static void test_multi_hop_confirms_after_the_next_router(void)
{
	gw_hop hop = { .line = 2, .node = 0x20, .via_router = true };
	uint8_t confirm[8] = { 0xE0, 9, 0, 5, 0, 0, 0, 0 };
	uint8_t up[8] = { 0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0 };
	uint8_t resp[8] = { 0x43, 0x00, 0x10, 0x00, 0x91, 0x01, 0x0F, 0x00 };

	gw_sdo_route_start(&s, (gw_netind){ 9, 5 }, 0, &hop, 1000, 3000, 0);
	TEST_ASSERT_EQUAL(0x20, opened_hop.node);
	TEST_ASSERT_EQUAL(GW_SR_HOP, gw_sdo_route_state_of(&s));
	hex_eq("E0 09 00 05 00 00 00 00", last_to_tgt);
	TEST_ASSERT_EQUAL(0, n_to_req); /* not confirmed before the router */
	TEST_ASSERT_EQUAL_UINT64(3000000, gw_sdo_route_deadline(&s));
	gw_sdo_route_target_frame(&s, confirm, 10);
	hex_eq("E0 09 00 05 00 00 00 00", last_to_req);
	gw_sdo_route_requester_frame(&s, up, 20);
	TEST_ASSERT_EQUAL_MEMORY(up, last_to_tgt, 8);
	gw_sdo_route_target_frame(&s, resp, 30);
	TEST_ASSERT_EQUAL_MEMORY(resp, last_to_req, 8);
	TEST_ASSERT_EQUAL(1, dones);
	TEST_ASSERT_EQUAL(GW_OUT_ROUTED, done_outcome);
	TEST_ASSERT_EQUAL(1, closes);
}

static void test_next_router_refusal_is_passed_back(void)
{
	gw_hop hop = { .line = 2, .node = 0x20, .via_router = true };
	uint8_t refusal[8] = { 0x80, 9, 0, 5, 0x01, 0, 0, 0x0A };

	gw_sdo_route_start(&s, (gw_netind){ 9, 5 }, 0, &hop, 1000, 1000, 0);
	gw_sdo_route_target_frame(&s, refusal, 10);
	TEST_ASSERT_EQUAL_MEMORY(refusal, last_to_req, 8);
	TEST_ASSERT_EQUAL(GW_OUT_REFUSED, done_outcome);
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NET_UNKNOWN, done_abort);
	TEST_ASSERT_EQUAL(1, closes);
}

static void test_timeouts(void)
{
	gw_hop hop = { .line = 1, .node = TGT_ID };
	uint8_t init[8] = { 0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0 };
	uint8_t seg_init[8] = { 0x41, 0x08, 0x10, 0x00, 30, 0, 0, 0 };

	/* confirmed, and the requester never sends its initiate */
	gw_sdo_route_start(&s, (gw_netind){ NET, TGT_ID }, 0, &hop, 500, 800, 0);
	hex_eq("E0 02 00 05 00 00 00 00", last_to_req);
	gw_sdo_route_tick(&s, 499999);
	TEST_ASSERT_EQUAL(0, dones);
	gw_sdo_route_tick(&s, 500000);
	hex_eq("80 02 00 05 00 00 04 05", last_to_req);
	TEST_ASSERT_EQUAL(GW_OUT_TIMED_OUT, done_outcome);
	TEST_ASSERT_EQUAL(1, closes);
	TEST_ASSERT_EQUAL(0, n_to_tgt);

	/* the target never answers the initiate: node silent */
	gw_sdo_route_start(&s, (gw_netind){ NET, TGT_ID }, 0, &hop, 500, 800, 1000000);
	gw_sdo_route_requester_frame(&s, init, 1100000);
	gw_sdo_route_tick(&s, 1900000);
	hex_eq("80 18 10 01 02 00 00 0A", last_to_req);
	hex_eq("80 18 10 01 00 00 04 05", last_to_tgt);
	TEST_ASSERT_EQUAL(GW_OUT_TIMED_OUT, done_outcome);

	/* the target answered, then went silent: SDO timeout */
	gw_sdo_route_start(&s, (gw_netind){ NET, TGT_ID }, 0, &hop, 500, 800, 2000000);
	init[1] = 0x08;
	init[3] = 0;
	gw_sdo_route_requester_frame(&s, init, 2000000);
	gw_sdo_route_target_frame(&s, seg_init, 2000000);
	TEST_ASSERT_EQUAL(GW_SR_UP_SEG_REQ, gw_sdo_route_state_of(&s));
	/* ... and the requester vanishes: 500 ms later both get an abort */
	gw_sdo_route_tick(&s, 2500000);
	hex_eq("80 08 10 00 00 00 04 05", last_to_req);
	hex_eq("80 08 10 00 00 00 04 05", last_to_tgt);
	TEST_ASSERT_EQUAL(3, dones);
	TEST_ASSERT_EQUAL(3, closes);
}

static void test_requester_vanishing_in_a_block_download_releases_both(void)
{
	co_od_entry *e = co_od_find(tgt->od, FX_IDX_DOMAIN, 0);
	uint8_t init[8] = { 0xC6, 0x00, 0x22, 0x00, 0x00, 0x10, 0, 0 }; /* 4096 bytes */
	uint8_t seg[8] = { 0x01, 1, 2, 3, 4, 5, 6, 7 };

	(void)e;
	indicate();
	gw_sdo_route_requester_frame(&s, init, bus_a.now);
	pump();
	TEST_ASSERT_EQUAL(GW_SR_BLK_DN_SUB, gw_sdo_route_state_of(&s));
	for (uint8_t i = 1; i <= 5; i++) {
		seg[0] = i;
		gw_sdo_route_requester_frame(&s, seg, bus_a.now);
	}
	pump();
	/* the requester is gone: the session times out, both ends released */
	for (int i = 0; i < 30 && gw_sdo_route_busy(&s); i++)
		advance(100000);
	TEST_ASSERT_FALSE(gw_sdo_route_busy(&s));
	TEST_ASSERT_EQUAL(GW_OUT_TIMED_OUT, done_outcome);
	TEST_ASSERT_EQUAL(1, closes);
	TEST_ASSERT_EQUAL(CO_EV_SDO_SERVER_DONE, tb_last_event(tgt, CO_EV_SDO_SERVER_DONE)->kind);
	TEST_ASSERT_NOT_EQUAL(0, tb_last_event(tgt, CO_EV_SDO_SERVER_DONE)->u.sdo_srv.abort);
}

static void test_protocol_errors_and_aborts(void)
{
	uint8_t bad[8] = { 0x60, 0, 0, 0, 0, 0, 0, 0 }; /* upload segment first */
	uint8_t init[8] = { 0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0 };
	uint8_t ab[8] = { 0x80, 0x00, 0x10, 0x00, 0x00, 0x00, 0x02, 0x06 };

	indicate();
	gw_sdo_route_requester_frame(&s, bad, bus_a.now);
	hex_eq("80 02 00 05 01 00 04 05", last_to_req);
	TEST_ASSERT_EQUAL(0, n_to_tgt); /* nothing reached the target yet */
	TEST_ASSERT_EQUAL(GW_OUT_ABORTED, done_outcome);

	pump();
	indicate();
	gw_sdo_route_requester_frame(&s, init, bus_a.now);
	gw_sdo_route_target_frame(&s, ab, bus_a.now); /* the target's abort */
	TEST_ASSERT_EQUAL_MEMORY(ab, last_to_req, 8);
	TEST_ASSERT_EQUAL_HEX32(0x06020000, done_abort);
	TEST_ASSERT_EQUAL(GW_OUT_ABORTED, done_outcome);

	pump();
	indicate();
	gw_sdo_route_requester_frame(&s, init, bus_a.now);
	gw_sdo_route_requester_frame(&s, init, bus_a.now); /* not its turn */
	hex_eq("80 00 10 00 01 00 04 05", last_to_req);
	hex_eq("80 00 10 00 01 00 04 05", last_to_tgt);

	pump();
	indicate();
	gw_sdo_route_cancel(&s, SDO_AB_GENERAL, bus_a.now);
	hex_eq("80 02 00 05 00 00 00 08", last_to_req);
	TEST_ASSERT_FALSE(gw_sdo_route_busy(&s));
	TEST_ASSERT_EQUAL(opens, closes);
	TEST_ASSERT_EQUAL_STRING("block upload sub-block",
				 gw_sdo_route_state_to_string(GW_SR_BLK_UP_SUB));
}

/* The target line could not bind the lease it was told of (its state
 * changed since the reservation): the requester already has the
 * confirmation and sends the transfer it announced. That initiate is
 * answered with the code, carrying its own multiplexer (an abort sent
 * before it would name no transfer of the requester's, and the initiate
 * would reach the gateway's own SDO server); the close is owed once. */
static void test_lease_lost_after_the_confirmation(void)
{
	uint8_t init[8] = { 0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0 };
	unsigned sent_before;

	indicate();
	sent_before = n_to_req;
	gw_sdo_route_lost(&s, GW_AB_NO_ANSWER, bus_a.now);
	TEST_ASSERT_EQUAL(sent_before, n_to_req); /* nothing before the initiate */
	TEST_ASSERT_TRUE(gw_sdo_route_busy(&s));  /* the initiate is still the session's */
	gw_sdo_route_requester_frame(&s, init, bus_a.now);
	hex_eq("80 00 10 00 02 00 00 0A", last_to_req);
	TEST_ASSERT_EQUAL(1, dones);
	TEST_ASSERT_EQUAL(GW_OUT_ABORTED, done_outcome);
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NO_ANSWER, done_abort);
	TEST_ASSERT_EQUAL(1, closes);
	TEST_ASSERT_EQUAL(0, n_to_tgt);
	TEST_ASSERT_FALSE(gw_sdo_route_busy(&s));

	/* the requester gave up meanwhile (its own abort): nothing to answer */
	pump();
	indicate();
	sent_before = n_to_req;
	gw_sdo_route_lost(&s, GW_AB_NO_ANSWER, bus_a.now);
	uint8_t ab[8] = { 0x80, 0x00, 0x10, 0x00, 0x00, 0x00, 0x04, 0x05 };
	gw_sdo_route_requester_frame(&s, ab, bus_a.now);
	TEST_ASSERT_EQUAL(sent_before, n_to_req);
	TEST_ASSERT_FALSE(gw_sdo_route_busy(&s));
	TEST_ASSERT_EQUAL(opens, closes);
}

/* A frame of the target before the initiate answers another client of the
 * same server channel (on a real bus: one that just ended its own transfer
 * with the device): the session goes on and relays the transfer. */
static void test_target_frame_before_the_initiate_is_not_the_sessions(void)
{
	uint8_t stray[8] = { 0x60, 0x00, 0x2F, 0x00, 0, 0, 0, 0 };
	uint8_t stray_abort[8] = { 0x80, 0x00, 0x2F, 0x00, 0x00, 0x00, 0x04, 0x05 };
	uint32_t v = 0;
	sdo_client_req r = {
		.upload = true, .node_id = GW_ID, .index = 0x1000, .buf = (uint8_t *)&v, .cap = 4
	};

	indicate();
	gw_sdo_route_target_frame(&s, stray, bus_a.now);
	gw_sdo_route_target_frame(&s, stray_abort, bus_a.now);
	TEST_ASSERT_EQUAL(GW_SR_WAIT_INIT, gw_sdo_route_state_of(&s));
	const co_event *ev = client_run(&r);
	TEST_ASSERT_EQUAL_HEX32(0, ev->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL(GW_OUT_ROUTED, done_outcome);
}

static void test_target_line_lost_mid_transfer(void)
{
	uint8_t init[8] = { 0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0 };

	indicate();
	gw_sdo_route_requester_frame(&s, init, bus_a.now);
	gw_sdo_route_lost(&s, GW_AB_NO_ANSWER, bus_a.now);
	hex_eq("80 00 10 00 02 00 00 0A", last_to_req);
	TEST_ASSERT_EQUAL(1, dones);
	TEST_ASSERT_EQUAL(1, closes);
}

/* ---- the lending board: a reservation decided at once, never lent twice ---- */

static gw_lend board;

static void tgt_raw(void *arg, const uint8_t d[8], uint64_t now_us)
{
	(void)arg;
	(void)d;
	(void)now_us;
}
static tb_port *lender; /* the target line's own node with its client pool */

static void lender_on(void)
{
	co_node_config cfg = { .node_id = 0x7E,
			       .sdo_client_count = 2,
			       .sdo_client_queue_len = 2,
			       .sdo_client_pool_len = 4,
			       .sdo_client_timeout_ms = 500 };
	co_od *od;

	TEST_ASSERT_EQUAL(0, co_od_create(&od, 8));
	bus_b.log_on = true; /* own_requests_to */
	lender = tb_add_node(&bus_b, &cfg, od);
	TEST_ASSERT_NOT_NULL(lender);
	gw_lend_init(&board);
	sdo_client_set_gate(lender->node, gw_lend_gate, &board);
	gw_lend_set_carries(&board, true);
}

/* A read by the target line's own pool (its mailbox clients, its manager). */
static void own_read(uint8_t node, uint64_t tag)
{
	static uint8_t rd[8];
	sdo_client_req r = { .upload = true,
			     .node_id = node,
			     .index = 0x1000,
			     .buf = rd,
			     .cap = sizeof rd,
			     .tag = tag };

	TEST_ASSERT_EQUAL(0, sdo_client_pool_submit(lender->node, &r, bus_b.now));
}

static size_t own_requests_to(uint8_t node)
{
	return tb_count_from_id(&bus_b, lender->idx, 0x600u + node, 0);
}

/* A reservation of line 0 that takes nothing over. */
static uint32_t reserve(uint8_t node, uint8_t *channel)
{
	bool taken = true;
	uint32_t refuse = gw_lend_reserve(&board, 0, node, channel, &taken);

	TEST_ASSERT_FALSE(taken);
	return refuse;
}

static void test_reservation_refusals_keep_their_codes(void)
{
	uint8_t a = 0xFF, b = 0xFF, c;
	uint64_t lost[2] = { 1ull << 8, 0 };

	lender_on();
	TEST_ASSERT_EQUAL_HEX32(0, reserve(5, &a));
	/* the node is in a routed transfer already */
	TEST_ASSERT_EQUAL_HEX32(GW_AB_ROUTE_BUSY, reserve(5, &c));
	TEST_ASSERT_EQUAL_HEX32(0, reserve(6, &b));
	TEST_ASSERT_TRUE(a < 2 && b < 2 && a != b);
	/* no channel left: "no free client", and node 7 is not left reserved */
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NO_CLIENT, reserve(7, &c));
	gw_lend_give_back(&board, b, 6);
	TEST_ASSERT_EQUAL_HEX32(0, reserve(7, &c));
	TEST_ASSERT_EQUAL(b, c);
	/* heartbeat lost, line down: no answer, before anything else */
	gw_lend_set_silent(&board, lost);
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NO_ANSWER, reserve(8, &c));
	gw_lend_set_carries(&board, false);
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NO_ANSWER, reserve(9, &c));
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NO_ANSWER, reserve(5, &c));
}

/* A lease that ended well is offered until the owner ends it at the
 * M_CLOSE: of the next transfer toward that node (of its line or of
 * another) and the owner, exactly one gets it, and the owner's end frees
 * the node in the same step. */
static void test_lease_ended_well_is_handed_over_once(void)
{
	uint8_t a, c, taker = 0xFF;
	bool taken;

	lender_on();
	TEST_ASSERT_EQUAL_HEX32(0, reserve(5, &a));
	/* the next transfer first: it takes the lease, once */
	gw_lend_offer(&board, 0, 5, a);
	TEST_ASSERT_EQUAL_HEX32(0, gw_lend_reserve(&board, 0, 5, &c, &taken));
	TEST_ASSERT_TRUE(taken);
	TEST_ASSERT_EQUAL(a, c);
	TEST_ASSERT_EQUAL_HEX32(GW_AB_ROUTE_BUSY, gw_lend_reserve(&board, 0, 5, &c, &taken));
	TEST_ASSERT_FALSE(taken);
	TEST_ASSERT_EQUAL(5,
			  gw_lend_end_offered(&board, 0, 5, a, &taker)); /* kept: the node held */
	TEST_ASSERT_EQUAL(0, taker);
	TEST_ASSERT_EQUAL_HEX32(GW_AB_ROUTE_BUSY, reserve(5, &c));
	/* another line's transfer takes it the same way, the owner keeps it
	 * for that line */
	gw_lend_offer(&board, 0, 5, a);
	TEST_ASSERT_EQUAL_HEX32(0, gw_lend_reserve(&board, 2, 5, &c, &taken));
	TEST_ASSERT_TRUE(taken);
	TEST_ASSERT_EQUAL(a, c);
	TEST_ASSERT_FALSE(gw_lend_untake(&board, 0, 5, a, 5)); /* line 0 did not take it */
	TEST_ASSERT_EQUAL(5, gw_lend_end_offered(&board, 0, 5, a, &taker));
	TEST_ASSERT_EQUAL(2, taker);
	/* the owner first: the node is free in the same step */
	gw_lend_offer(&board, 0, 5, a);
	TEST_ASSERT_EQUAL(0, gw_lend_end_offered(&board, 0, 5, a, &taker));
	TEST_ASSERT_EQUAL_HEX32(0, gw_lend_reserve(&board, 0, 5, &c, &taken));
	TEST_ASSERT_FALSE(taken);
	TEST_ASSERT_TRUE(c != a);
	gw_lend_give_back(&board, c, 5);
	/* taken for another node (every channel held): the old node goes
	 * free, the new one stays held */
	TEST_ASSERT_TRUE(gw_lend_claim_node(&board, 5));
	TEST_ASSERT_TRUE(gw_lend_claim_node(&board, 8));
	gw_lend_offer(&board, 0, 5, a);
	TEST_ASSERT_FALSE(gw_lend_take_offer(&board, 1, 5, a, 8)); /* not line 1's */
	TEST_ASSERT_TRUE(gw_lend_take_offer(&board, 0, 5, a, 8));
	TEST_ASSERT_EQUAL(8, gw_lend_end_offered(&board, 0, 5, a, &taker));
	TEST_ASSERT_TRUE(gw_lend_claim_node(&board, 5));
	TEST_ASSERT_FALSE(gw_lend_claim_node(&board, 8));
	/* the M_OPEN not sent: an offer again, unless the owner kept it */
	gw_lend_offer(&board, 0, 5, a);
	TEST_ASSERT_TRUE(gw_lend_take_offer(&board, 0, 5, a, 5));
	TEST_ASSERT_TRUE(gw_lend_untake(&board, 0, 5, a, 5));
	TEST_ASSERT_EQUAL(0, gw_lend_end_offered(&board, 0, 5, a, &taker));
	TEST_ASSERT_TRUE(gw_lend_claim_node(&board, 5));
	gw_lend_offer(&board, 0, 5, a);
	TEST_ASSERT_TRUE(gw_lend_take_offer(&board, 0, 5, a, 5));
	TEST_ASSERT_EQUAL(5, gw_lend_end_offered(&board, 0, 5, a, &taker));
	TEST_ASSERT_FALSE(gw_lend_untake(&board, 0, 5, a, 5));
	/* the M_CLOSE not sent: withdrawn, the node still held */
	gw_lend_offer(&board, 0, 5, a);
	gw_lend_withdraw(&board, 0, 5, a);
	TEST_ASSERT_FALSE(gw_lend_take_offer(&board, 0, 5, a, 5));
	TEST_ASSERT_EQUAL_HEX32(GW_AB_ROUTE_BUSY, reserve(5, &c));
	/* a free node has nothing to offer */
	gw_lend_node_free(&board, 5);
	gw_lend_offer(&board, 0, 5, a);
	TEST_ASSERT_FALSE(gw_lend_take_offer(&board, 0, 5, a, 5));
}

/* A lease kept for the next transfer moves to that transfer's node
 * without going back in between: the own pool's request waiting for the
 * old node gets no channel from it (it starts on the next one freed); the
 * lease's frames go to the new node. */
static void test_kept_lease_moves_to_the_next_node(void)
{
	uint8_t a;

	lender_on();
	TEST_ASSERT_EQUAL_HEX32(0, reserve(5, &a));
	TEST_ASSERT_EQUAL(a,
			  sdo_client_lease_channel(lender->node, a, 5, tgt_raw, NULL, bus_b.now));
	own_read(7, 2); /* on the other channel */
	own_read(5, 1); /* waits for the node */
	TEST_ASSERT_EQUAL(1, own_requests_to(7));
	TEST_ASSERT_TRUE(gw_lend_claim_node(&board, 8));
	gw_lend_node_free(&board, 5); /* the old node first, as gw_relay does */
	TEST_ASSERT_EQUAL(0, sdo_client_lease_move(lender->node, a, 8, bus_b.now));
	TEST_ASSERT_EQUAL(0, own_requests_to(5));
	TEST_ASSERT_EQUAL(0, sdo_client_lease_send(lender->node, a, (const uint8_t[8]){ 0x40 }));
	TEST_ASSERT_EQUAL(1, tb_count_from_id(&bus_b, lender->idx, 0x608u, 0));
	/* the node in a transfer elsewhere, a channel not leased, a bad node */
	TEST_ASSERT_EQUAL(-EALREADY, sdo_client_lease_move(lender->node, a, 7, bus_b.now));
	TEST_ASSERT_EQUAL(-ENOENT,
			  sdo_client_lease_move(lender->node, (uint8_t)(1 - a), 9, bus_b.now));
	TEST_ASSERT_EQUAL(-EINVAL, sdo_client_lease_move(lender->node, a, 0, bus_b.now));
	/* node 7's read times out: node 5's starts on that channel */
	tb_advance(&bus_b, 500000);
	TEST_ASSERT_EQUAL(1, own_requests_to(5));
	TEST_ASSERT_EQUAL(0, sdo_client_lease_send(lender->node, a, (const uint8_t[8]){ 0x40 }));
	TEST_ASSERT_EQUAL(2, tb_count_from_id(&bus_b, lender->idx, 0x608u, 0));
}

/* What the target line's own clients hold is not lent, and what is lent
 * is not given to them; a unit given back lets them go on. */
static void test_reservation_and_own_clients_exclude_each_other(void)
{
	uint8_t a, b, c;

	lender_on();
	/* the own pool busy with node 11 on one channel */
	own_read(11, 1);
	TEST_ASSERT_EQUAL(1, own_requests_to(11));
	TEST_ASSERT_EQUAL_HEX32(GW_AB_ROUTE_BUSY, reserve(11, &c));
	TEST_ASSERT_EQUAL_HEX32(0, reserve(5, &a));
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NO_CLIENT, reserve(6, &c));
	/* an own request meets no channel (the idle one is reserved) nor the
	 * reserved node */
	own_read(12, 2);
	own_read(5, 3);
	TEST_ASSERT_EQUAL(0, own_requests_to(12));
	TEST_ASSERT_EQUAL(0, own_requests_to(5));
	/* the lease is bound on exactly the reserved channel */
	TEST_ASSERT_EQUAL(-EINVAL,
			  sdo_client_lease_channel(lender->node, a, 5, NULL, NULL, bus_b.now));
	TEST_ASSERT_EQUAL(a,
			  sdo_client_lease_channel(lender->node, a, 5, tgt_raw, NULL, bus_b.now));
	/* node 11 times out: its channel is back, node 12 takes it */
	tb_advance(&bus_b, 500000);
	TEST_ASSERT_EQUAL(1, own_requests_to(12));
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NO_CLIENT, reserve(6, &c));
	/* the lease ends (the channel first, then the node, as gw_relay
	 * does): node 5 goes at once */
	TEST_ASSERT_EQUAL(0, sdo_client_lease_end(lender->node, a, bus_b.now));
	TEST_ASSERT_EQUAL(0, own_requests_to(5));
	gw_lend_node_free(&board, 5);
	sdo_client_gate_kick(lender->node, bus_b.now);
	TEST_ASSERT_EQUAL(1, own_requests_to(5));
	tb_advance(&bus_b, 500000); /* both time out: nothing held any more */
	tb_advance(&bus_b, 100000); /* their servers settle */
	TEST_ASSERT_EQUAL_HEX32(0, reserve(11, &b));
	TEST_ASSERT_EQUAL_HEX32(0, reserve(5, &c));
	TEST_ASSERT_TRUE(b != c);
}

/* ---- the target line's end of a lease (gateway/gw_relay.c) ---- */

static gw tgw; /* of which line 2, the target, is used: its leases send nothing here */
static struct gw_line *tl;
/* Another line's reservation toward race_node, made inside the owner's
 * end of a lease just before the channel comes back to the board: the
 * moment two threads meet at. */
static uint8_t race_node, race_ch;
static uint32_t race_refuse;
static bool race_taken;

static bool racing_gate(void *ctx, sdo_client_gate_op op, uint8_t arg)
{
	if (op == SDO_CLIENT_GATE_FREE_CHANNEL && race_node) {
		race_refuse = gw_lend_reserve(ctx, 1, race_node, &race_ch, &race_taken);
		race_node = 0;
	}
	return gw_lend_gate(ctx, op, arg);
}

static void target_line_on(void)
{
	lender_on();
	memset(&tgw, 0, sizeof tgw);
	tl = &tgw.line[2];
	tl->g = &tgw;
	tl->idx = 2;
	tl->node = lender->node;
	tl->carried = true;
	tl->p.sdo_timeout_ms = 500;
	gw_lend_init(&tl->lend);
	gw_lend_set_carries(&tl->lend, true);
	sdo_client_set_gate(lender->node, racing_gate, &tl->lend);
}

static gw_msg open_msg(uint8_t from, uint32_t sid, uint8_t node, uint8_t ch, bool inherits)
{
	return (gw_msg){ .kind = M_OPEN,
			 .from = from,
			 .sid = sid,
			 .node = node,
			 .channel = ch,
			 .inherits = inherits };
}

/* Line 0's lease toward node, bound by its M_OPEN: its channel. */
static uint8_t bound_lease(uint32_t sid, uint8_t node)
{
	uint8_t ch;
	bool taken;
	gw_msg m;

	TEST_ASSERT_EQUAL_HEX32(0, gw_lend_reserve(&tl->lend, 0, node, &ch, &taken));
	m = open_msg(0, sid, node, ch, false);
	gw_relay_open(tl, &m, bus_b.now);
	return ch;
}

static const struct gw_relay *relay_of(uint8_t from, uint32_t sid)
{
	for (unsigned i = 0; i < GW_RELAYS_MAX; i++)
		if (tl->relay[i].used && !tl->relay[i].parked && tl->relay[i].from == from &&
		    tl->relay[i].sid == sid)
			return &tl->relay[i];
	return NULL;
}

static void close_well(uint32_t sid, uint8_t node, uint8_t ch)
{
	gw_msg m = { .kind = M_CLOSE, .from = 0, .sid = sid, .channel = ch };

	gw_lend_offer(&tl->lend, 0, node, ch);
	gw_relay_close(tl, &m, bus_b.now);
}

/* Every channel lent, a lease ending well: a transfer toward its node that
 * comes while the owner ends it finds the lease (taken over, bound again
 * for it) or the node and the channel both free, never the node free and
 * no channel ("no free client" for a channel a moment from free). */
static void test_lease_nobody_took_ends_channel_first(void)
{
	uint8_t a, b, c;
	bool taken;
	gw_msg m;
	size_t sent;

	target_line_on();
	a = bound_lease(0x00000001, 5);
	b = bound_lease(0x00010001, 6);
	TEST_ASSERT_TRUE(a != b && relay_of(0, 0x00010001));
	/* line 1's transfer toward node 6 while the owner ends line 0's
	 * lease: it takes it, and its M_OPEN finds it bound */
	race_node = 6;
	close_well(0x00010001, 6, b);
	TEST_ASSERT_EQUAL_HEX32(0, race_refuse);
	TEST_ASSERT_TRUE(race_taken);
	TEST_ASSERT_EQUAL(b, race_ch);
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NO_CLIENT, gw_lend_reserve(&tl->lend, 0, 7, &c, &taken));
	m = open_msg(1, 0x01000001, 6, b, true);
	gw_relay_open(tl, &m, bus_b.now);
	TEST_ASSERT_NOT_NULL(relay_of(1, 0x01000001));
	TEST_ASSERT_EQUAL(0, sdo_client_lease_send(lender->node, b, (const uint8_t[8]){ 0x40 }));
	TEST_ASSERT_EQUAL(1, tb_count_from_id(&bus_b, lender->idx, 0x606u, 0));
	/* nobody takes it: the node and its channel free together, and the
	 * pool's read waiting for the node starts at once */
	m = (gw_msg){ .kind = M_CLOSE, .from = 1, .sid = 0x01000001, .channel = b };
	gw_relay_close(tl, &m, bus_b.now);
	b = bound_lease(0x00010002, 6);
	sent = own_requests_to(6); /* the lease's frame */
	own_read(6, 1);
	TEST_ASSERT_EQUAL(sent, own_requests_to(6));
	close_well(0x00010002, 6, b);
	TEST_ASSERT_NULL(relay_of(0, 0x00010002));
	TEST_ASSERT_EQUAL(sent + 1, own_requests_to(6));
	/* the other lease, ended well, and a reservation right after: both
	 * free */
	close_well(0x00000001, 5, a);
	TEST_ASSERT_EQUAL_HEX32(0, gw_lend_reserve(&tl->lend, 0, 5, &c, &taken));
	TEST_ASSERT_FALSE(taken);
	TEST_ASSERT_EQUAL(a, c);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_every_mode_and_size_arrives_byte_exact);
	RUN_TEST(test_expedited_frames_are_relayed_unchanged);
	RUN_TEST(test_answers_sent_across_are_those_the_session_forwards);
	RUN_TEST(test_refusals_come_at_once);
	RUN_TEST(test_multi_hop_confirms_after_the_next_router);
	RUN_TEST(test_next_router_refusal_is_passed_back);
	RUN_TEST(test_timeouts);
	RUN_TEST(test_requester_vanishing_in_a_block_download_releases_both);
	RUN_TEST(test_protocol_errors_and_aborts);
	RUN_TEST(test_lease_lost_after_the_confirmation);
	RUN_TEST(test_target_frame_before_the_initiate_is_not_the_sessions);
	RUN_TEST(test_target_line_lost_mid_transfer);
	RUN_TEST(test_reservation_refusals_keep_their_codes);
	RUN_TEST(test_reservation_and_own_clients_exclude_each_other);
	RUN_TEST(test_lease_ended_well_is_handed_over_once);
	RUN_TEST(test_kept_lease_moves_to_the_next_node);
	RUN_TEST(test_lease_nobody_took_ends_channel_first);
	return UNITY_END();
}
