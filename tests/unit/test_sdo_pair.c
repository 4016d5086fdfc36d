/* SPDX-License-Identifier: MIT */
/*
 * SDO client and server as two core instances wired in memory: every size
 * class (0, 1-4, 5-7, 8-889, >= 890) in every mode, both directions;
 * 100 KiB block transfers with CRC, lost and repeated segments; streaming
 * through chunk callbacks; fallback from block to segmented.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "unity.h"

#include "core/co.h"
#include "core/sdo_client.h"
#include "core/sdo_server.h"
#include "tests/unit/support/test_bus.h"
#include "tests/unit/support/test_od_fixture.h"

#define SRV_ID 5

static tb_bus bus;
static tb_port *srv;
static tb_port *cli;
static uint8_t *big_in, *big_out;

static void make_pair(bool server_no_block)
{
	co_node_config scfg = { .node_id = SRV_ID, .sdo_server_no_block = server_no_block };
	co_node_config ccfg = { .node_id = 1, .sdo_client_count = 2 };
	co_od *cod;

	tb_init(&bus);
	srv = tb_add_node(&bus, &scfg, fx_od_new());
	TEST_ASSERT_NOT_NULL(srv);
	TEST_ASSERT_EQUAL(0, co_od_create(&cod, 16));
	cli = tb_add_node(&bus, &ccfg, cod);
	TEST_ASSERT_NOT_NULL(cli);
}

void setUp(void)
{
	make_pair(false);
	big_in = malloc(FX_DOMAIN_MAX);
	big_out = malloc(FX_DOMAIN_MAX);
	TEST_ASSERT_NOT_NULL(big_in);
	TEST_ASSERT_NOT_NULL(big_out);
	for (uint32_t i = 0; i < FX_DOMAIN_MAX; i++)
		big_in[i] = (uint8_t)(i * 31u + (i >> 9));
}

void tearDown(void)
{
	tb_fini(&bus);
	free(big_in);
	free(big_out);
}

static const co_event *run(const sdo_client_req *r)
{
	size_t before = tb_event_count(cli, CO_EV_SDO_CLIENT_DONE);

	TEST_ASSERT_EQUAL(0, sdo_client_submit(cli->node, 0, r, bus.now));
	tb_settle(&bus, 60000000);
	TEST_ASSERT_EQUAL_MESSAGE(before + 1, tb_event_count(cli, CO_EV_SDO_CLIENT_DONE),
				  "no completion");
	return tb_last_event(cli, CO_EV_SDO_CLIENT_DONE);
}

static const co_event *download(uint16_t idx, const uint8_t *data, uint32_t size, uint8_t mode)
{
	sdo_client_req r = { .node_id = SRV_ID,
			     .index = idx,
			     .sub = 0,
			     .mode = mode,
			     .data = data,
			     .size = size,
			     .tag = 0xD0 + size };
	return run(&r);
}

static const co_event *upload(uint16_t idx, uint8_t *buf, uint32_t cap, uint8_t mode, uint32_t hint)
{
	sdo_client_req r = { .upload = true,
			     .node_id = SRV_ID,
			     .index = idx,
			     .sub = 0,
			     .mode = mode,
			     .buf = buf,
			     .cap = cap,
			     .size = hint,
			     .tag = 0x0A };
	return run(&r);
}

static uint8_t expected_mode(uint8_t hint, uint32_t size, bool upload_dir)
{
	if (upload_dir) {
		if (hint == SDO_MODE_BLOCK)
			return SDO_MODE_BLOCK;
		return size >= 1 && size <= 4 ? SDO_MODE_EXPEDITED : SDO_MODE_SEGMENTED;
	}
	switch (hint) {
	case SDO_MODE_BLOCK:
		return SDO_MODE_BLOCK;
	case SDO_MODE_SEGMENTED:
		return SDO_MODE_SEGMENTED;
	case SDO_MODE_EXPEDITED:
		return size >= 1 && size <= 4 ? SDO_MODE_EXPEDITED : SDO_MODE_SEGMENTED;
	default:
		if (size >= 1 && size <= 4)
			return SDO_MODE_EXPEDITED;
		return size >= 128 ? SDO_MODE_BLOCK : SDO_MODE_SEGMENTED;
	}
}

static void roundtrip(uint16_t idx, uint32_t size, uint8_t mode)
{
	char msg[96];
	const co_event *ev;
	co_od_entry *e = co_od_find(srv->od, idx, 0);

	snprintf(msg, sizeof(msg), "idx %04X size %u mode %s", idx, size,
		 sdo_mode_to_string((sdo_mode)mode));
	ev = download(idx, big_in, size, mode);
	TEST_ASSERT_EQUAL_HEX32_MESSAGE(0, ev->u.sdo_cli.abort, msg);
	TEST_ASSERT_EQUAL_UINT32_MESSAGE(size, ev->u.sdo_cli.size, msg);
	TEST_ASSERT_EQUAL_MESSAGE(expected_mode(mode, size, false), ev->u.sdo_cli.mode, msg);
	TEST_ASSERT_EQUAL_UINT64_MESSAGE(0xD0 + size, ev->u.sdo_cli.tag, msg);
	TEST_ASSERT_EQUAL_UINT32_MESSAGE(size, e->size, msg);
	if (size)
		TEST_ASSERT_EQUAL_MEMORY_MESSAGE(big_in, e->data, size, msg);

	memset(big_out, 0xEE, size + 8);
	ev = upload(idx, big_out, FX_DOMAIN_MAX, mode, 0);
	TEST_ASSERT_EQUAL_HEX32_MESSAGE(0, ev->u.sdo_cli.abort, msg);
	TEST_ASSERT_EQUAL_UINT32_MESSAGE(size, ev->u.sdo_cli.size, msg);
	TEST_ASSERT_EQUAL_MESSAGE(expected_mode(mode, size, true), ev->u.sdo_cli.mode, msg);
	TEST_ASSERT_EQUAL_PTR(big_out, ev->u.sdo_cli.data);
	if (size)
		TEST_ASSERT_EQUAL_MEMORY_MESSAGE(big_in, big_out, size, msg);
	TEST_ASSERT_EQUAL_HEX8_MESSAGE(0xEE, big_out[size], msg);
}

static const uint32_t sizes[] = { 0,   1,   2,   3,   4,   5,   6,   7,   8,   9,    13,   14,  15,
				  100, 127, 128, 888, 889, 890, 891, 895, 896, 1778, 1779, 5000 };
static const uint8_t modes[] = { SDO_MODE_AUTO, SDO_MODE_EXPEDITED, SDO_MODE_SEGMENTED,
				 SDO_MODE_BLOCK };

static void test_matrix_domain_in_place(void)
{
	for (size_t m = 0; m < sizeof(modes); m++)
		for (size_t s = 0; s < sizeof(sizes) / sizeof(sizes[0]); s++)
			roundtrip(FX_IDX_DOMAIN, sizes[s], modes[m]);
}

static void test_matrix_octet_string_staged(void)
{
	for (size_t m = 0; m < sizeof(modes); m++)
		for (size_t s = 0; s < sizeof(sizes) / sizeof(sizes[0]); s++)
			if (sizes[s] <= 1000)
				roundtrip(FX_IDX_OCTETS, sizes[s], modes[m]);
}

static void test_numeric_values_and_remote_aborts(void)
{
	uint8_t v4[4] = { 0xA4, 0x70, 0x9D, 0x3F };
	uint8_t out[8];
	const co_event *ev;
	sdo_client_req r = { .node_id = SRV_ID, .index = 0x2004, .sub = 1, .data = v4, .size = 4 };

	ev = run(&r);
	TEST_ASSERT_EQUAL_HEX32(0, ev->u.sdo_cli.abort);
	r = (sdo_client_req){ .upload = true,
			      .node_id = SRV_ID,
			      .index = 0x2004,
			      .sub = 1,
			      .buf = out,
			      .cap = sizeof(out) };
	ev = run(&r);
	TEST_ASSERT_EQUAL_UINT32(4, ev->u.sdo_cli.size);
	TEST_ASSERT_EQUAL_MEMORY(v4, out, 4);
	/* Remote aborts come back as data. */
	r.index = 0x2001;
	ev = run(&r);
	TEST_ASSERT_EQUAL_HEX32(0x06020000, ev->u.sdo_cli.abort);
	r = (sdo_client_req){ .node_id = SRV_ID, .index = 0x1000, .data = v4, .size = 4 };
	ev = run(&r);
	TEST_ASSERT_EQUAL_HEX32(0x06010002, ev->u.sdo_cli.abort);
	/* Too long for a U16, in every mode. */
	for (size_t m = 0; m < sizeof(modes); m++) {
		r = (sdo_client_req){ .node_id = SRV_ID,
				      .index = 0x1017,
				      .data = big_in,
				      .size = 300,
				      .mode = modes[m] };
		ev = run(&r);
		TEST_ASSERT_EQUAL_HEX32(0x06070012, ev->u.sdo_cli.abort);
	}
	/* Upload buffer too small: the client aborts with 0x05040005. */
	r = (sdo_client_req){
		.upload = true, .node_id = SRV_ID, .index = 0x1008, .buf = out, .cap = sizeof(out)
	};
	ev = run(&r);
	TEST_ASSERT_EQUAL_HEX32(0x05040005, ev->u.sdo_cli.abort);
	TB_ASSERT_LAST(&bus, 1, 0x605, "80 08 10 00 05 00 04 05");
	TEST_ASSERT_FALSE(sdo_server_busy(srv->node, 0));
}

/* ---- 100 KiB with loss and repetition ------------------------------------ */

struct fault {
	int from;         /* port whose frames are hit */
	uint64_t seen;    /* block segments from that port so far */
	uint64_t drop_at; /* 1-based segment count to drop (0 = none) */
	uint64_t dup_at;
	int dropped, duped;
};

static tb_action fault_filter(void *ctx, const co_frame *f, int from, uint64_t n)
{
	struct fault *fl = ctx;
	(void)n;
	if (from != fl->from || f->len != 8)
		return TB_DELIVER;
	/* Sub-block segments are the only frames that are not responses to
	 * something; they are recognisable by state, not by byte 0, so count
	 * all frames of the sender and aim at the middle of the transfer. */
	fl->seen++;
	if (fl->seen == fl->drop_at) {
		fl->dropped++;
		return TB_DROP;
	}
	if (fl->seen == fl->dup_at) {
		fl->duped++;
		return TB_DUP;
	}
	return TB_DELIVER;
}

static void big_block(uint32_t size, int drop_from)
{
	struct fault fl = { .from = drop_from, .drop_at = 300, .dup_at = 700 };
	const co_event *ev;
	co_od_entry *e = co_od_find(srv->od, FX_IDX_DOMAIN, 0);

	bus.filter = fault_filter;
	bus.filter_ctx = &fl;
	ev = download(FX_IDX_DOMAIN, big_in, size, SDO_MODE_BLOCK);
	TEST_ASSERT_EQUAL_HEX32(0, ev->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL(SDO_MODE_BLOCK, ev->u.sdo_cli.mode);
	TEST_ASSERT_EQUAL_UINT32(size, e->size);
	TEST_ASSERT_EQUAL_MEMORY(big_in, e->data, size);
	if (drop_from == cli->idx) {
		TEST_ASSERT_EQUAL(1, fl.dropped);
		TEST_ASSERT_EQUAL(1, fl.duped);
	}
	fl.seen = 0;
	fl.dropped = fl.duped = 0;
	fl.from = drop_from == cli->idx ? srv->idx : cli->idx;
	memset(big_out, 0, size);
	ev = upload(FX_IDX_DOMAIN, big_out, FX_DOMAIN_MAX, SDO_MODE_BLOCK, 0);
	TEST_ASSERT_EQUAL_HEX32(0, ev->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL_UINT32(size, ev->u.sdo_cli.size);
	TEST_ASSERT_EQUAL_MEMORY(big_in, big_out, size);
	if (fl.from == srv->idx) {
		TEST_ASSERT_EQUAL(1, fl.dropped);
		TEST_ASSERT_EQUAL(1, fl.duped);
	}
	bus.filter = NULL;
}

static void test_block_1k_lost_and_repeated(void)
{
	/* 1 KiB = 147 segments: aim inside the transfer. */
	struct fault fl = { .from = 1, .drop_at = 40, .dup_at = 100 };
	const co_event *ev;
	co_od_entry *e = co_od_find(srv->od, FX_IDX_DOMAIN, 0);

	bus.filter = fault_filter;
	bus.filter_ctx = &fl;
	ev = download(FX_IDX_DOMAIN, big_in, 1024, SDO_MODE_BLOCK);
	TEST_ASSERT_EQUAL_HEX32(0, ev->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL_UINT32(1024, e->size);
	TEST_ASSERT_EQUAL_MEMORY(big_in, e->data, 1024);
	TEST_ASSERT_EQUAL(1, fl.dropped);
	fl = (struct fault){ .from = 0, .drop_at = 40, .dup_at = 100 };
	ev = upload(FX_IDX_DOMAIN, big_out, FX_DOMAIN_MAX, SDO_MODE_BLOCK, 0);
	TEST_ASSERT_EQUAL_HEX32(0, ev->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL_MEMORY(big_in, big_out, 1024);
	TEST_ASSERT_EQUAL(1, fl.dropped);
	bus.filter = NULL;
}

/* CAN may deliver a frame twice (ACK error on its last bit). A repeated
 * copy of the segment that closes a sub-block, or of the very last
 * segment, must neither corrupt the data nor break the transfer. */
static void test_block_duplicate_sub_block_end_and_last_segment(void)
{
	const uint32_t size = 3 * 889 + 100; /* 3 full sub-blocks + 15 segments */
	/* Client frames: 1 initiate, then segments; #128 = seq 127 of the
	 * first sub-block; the last segment is #(1 + 3 * 127 + 15) = 397. */
	const uint64_t dups[] = { 128, 255, 397 };

	for (size_t i = 0; i < 3; i++) {
		struct fault fl = { .from = cli->idx, .dup_at = dups[i] };
		bus.filter = fault_filter;
		bus.filter_ctx = &fl;
		const co_event *ev = download(FX_IDX_DOMAIN, big_in, size, SDO_MODE_BLOCK);
		TEST_ASSERT_EQUAL_HEX32(0, ev->u.sdo_cli.abort);
		TEST_ASSERT_EQUAL(1, fl.duped);
		co_od_entry *e = co_od_find(srv->od, FX_IDX_DOMAIN, 0);
		TEST_ASSERT_EQUAL_UINT32(size, e->size);
		TEST_ASSERT_EQUAL_MEMORY(big_in, e->data, size);
		/* Server frames in an upload: 1 initiate response, then segments. */
		fl = (struct fault){ .from = srv->idx, .dup_at = dups[i] };
		memset(big_out, 0, size);
		ev = upload(FX_IDX_DOMAIN, big_out, FX_DOMAIN_MAX, SDO_MODE_BLOCK, 0);
		TEST_ASSERT_EQUAL_HEX32(0, ev->u.sdo_cli.abort);
		TEST_ASSERT_EQUAL(1, fl.duped);
		TEST_ASSERT_EQUAL_UINT32(size, ev->u.sdo_cli.size);
		TEST_ASSERT_EQUAL_MEMORY(big_in, big_out, size);
	}
	bus.filter = NULL;
}

static void test_block_100k_lost_and_repeated(void)
{
	big_block(100 * 1024, 1);
}

static void test_block_100k_clean_and_segmented(void)
{
	big_block(100 * 1024, -5); /* no faults */
	roundtrip(FX_IDX_DOMAIN, 100 * 1024, SDO_MODE_SEGMENTED);
}

/* ---- streaming --------------------------------------------------------- */

struct stream {
	uint32_t next; /* next offset expected / produced */
	uint32_t total;
	uint32_t calls;
	uint32_t bad;
	int fail_at; /* offset at which to fail (-1 = never) */
};

static uint8_t gen(uint32_t i)
{
	return (uint8_t)((i * 2654435761u) >> 24);
}

static int src_cb(void *ctx, uint32_t off, uint8_t *buf, uint32_t len)
{
	struct stream *s = ctx;
	if (off != s->next)
		s->bad++;
	if (s->fail_at >= 0 && off >= (uint32_t)s->fail_at)
		return -5;
	for (uint32_t i = 0; i < len; i++)
		buf[i] = gen(off + i);
	s->next = off + len;
	s->calls++;
	return (int)len;
}

static int sink_cb(void *ctx, uint32_t off, const uint8_t *data, uint32_t len, uint32_t total)
{
	struct stream *s = ctx;
	if (off != s->next)
		s->bad++;
	if (s->fail_at >= 0 && off >= (uint32_t)s->fail_at)
		return -5;
	for (uint32_t i = 0; i < len; i++)
		if (data[i] != gen(off + i))
			s->bad++;
	s->next = off + len;
	s->total = total;
	s->calls++;
	return 0;
}

static void test_streaming_domains(void)
{
	const uint32_t size = FX_DOMAIN_MAX;
	const uint8_t stream_modes[] = { SDO_MODE_BLOCK, SDO_MODE_SEGMENTED };

	for (size_t m = 0; m < sizeof(stream_modes); m++) {
		struct stream s = { .fail_at = -1 };
		sdo_client_req r = { .node_id = SRV_ID,
				     .index = FX_IDX_DOMAIN,
				     .size = size,
				     .src = src_cb,
				     .ctx = &s,
				     .mode = stream_modes[m] };
		const co_event *ev = run(&r);
		TEST_ASSERT_EQUAL_HEX32(0, ev->u.sdo_cli.abort);
		TEST_ASSERT_EQUAL_UINT32(size, s.next);
		TEST_ASSERT_EQUAL_UINT32(0, s.bad);

		struct stream k = { .fail_at = -1 };
		r = (sdo_client_req){ .upload = true,
				      .node_id = SRV_ID,
				      .index = FX_IDX_DOMAIN,
				      .sink = sink_cb,
				      .ctx = &k,
				      .mode = stream_modes[m] };
		ev = run(&r);
		TEST_ASSERT_EQUAL_HEX32(0, ev->u.sdo_cli.abort);
		TEST_ASSERT_EQUAL_UINT32(size, ev->u.sdo_cli.size);
		TEST_ASSERT_EQUAL_UINT32(size, k.next);
		TEST_ASSERT_EQUAL_UINT32(size, k.total);
		TEST_ASSERT_EQUAL_UINT32(0, k.bad);
		TEST_ASSERT_NULL(ev->u.sdo_cli.data);
	}
}

static void test_streaming_callback_failure_aborts(void)
{
	struct stream s = { .fail_at = 5000 };
	sdo_client_req r = { .node_id = SRV_ID,
			     .index = FX_IDX_DOMAIN,
			     .size = 20000,
			     .src = src_cb,
			     .ctx = &s,
			     .mode = SDO_MODE_BLOCK };
	const co_event *ev = run(&r);

	TEST_ASSERT_EQUAL_HEX32(0x08000020, ev->u.sdo_cli.abort);
	TEST_ASSERT_FALSE(sdo_server_busy(srv->node, 0));
	const co_event *sev = tb_last_event(srv, CO_EV_SDO_SERVER_DONE);
	TEST_ASSERT_EQUAL_HEX32(0x08000020, sev->u.sdo_srv.abort);

	/* The aborted in-place download left the value as it was (size 0):
	 * give the upload something to stream. */
	TEST_ASSERT_EQUAL(0, co_od_set_bytes(srv->od, FX_IDX_DOMAIN, 0, big_in, 20000));
	struct stream k = { .fail_at = 700 };
	r = (sdo_client_req){ .upload = true,
			      .node_id = SRV_ID,
			      .index = FX_IDX_DOMAIN,
			      .sink = sink_cb,
			      .ctx = &k,
			      .mode = SDO_MODE_SEGMENTED };
	ev = run(&r);
	TEST_ASSERT_EQUAL_HEX32(0x08000020, ev->u.sdo_cli.abort);
	TEST_ASSERT_FALSE(sdo_server_busy(srv->node, 0));
}

/* ---- fallback -------------------------------------------------------------- */

static void test_fallback_block_to_segmented(void)
{
	tb_fini(&bus);
	make_pair(true);
	const co_event *ev = download(FX_IDX_DOMAIN, big_in, 1000, SDO_MODE_AUTO);
	TEST_ASSERT_EQUAL_HEX32(0, ev->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL(SDO_MODE_SEGMENTED, ev->u.sdo_cli.mode);
	TEST_ASSERT_EQUAL_MEMORY(big_in, co_od_find(srv->od, FX_IDX_DOMAIN, 0)->data, 1000);
	ev = download(FX_IDX_DOMAIN, big_in, 3, SDO_MODE_BLOCK);
	TEST_ASSERT_EQUAL_HEX32(0, ev->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL(SDO_MODE_EXPEDITED, ev->u.sdo_cli.mode);
	ev = upload(FX_IDX_DOMAIN, big_out, FX_DOMAIN_MAX, SDO_MODE_BLOCK, 0);
	TEST_ASSERT_EQUAL_HEX32(0, ev->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL(SDO_MODE_EXPEDITED, ev->u.sdo_cli.mode);
	download(FX_IDX_DOMAIN, big_in, 5000, SDO_MODE_AUTO);
	ev = upload(FX_IDX_DOMAIN, big_out, FX_DOMAIN_MAX, SDO_MODE_AUTO, 5000);
	TEST_ASSERT_EQUAL_HEX32(0, ev->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL(SDO_MODE_SEGMENTED, ev->u.sdo_cli.mode);
	TEST_ASSERT_EQUAL_UINT32(5000, ev->u.sdo_cli.size);
	TEST_ASSERT_EQUAL_MEMORY(big_in, big_out, 5000);
}

static void test_auto_upload_block_with_protocol_switch(void)
{
	/* Size hint above the threshold -> block upload offered with pst 127;
	 * a 27-byte string makes the server switch to segmented. */
	const co_event *ev = upload(0x1008, big_out, 100, SDO_MODE_AUTO, 1000);
	TEST_ASSERT_EQUAL_HEX32(0, ev->u.sdo_cli.abort);
	TEST_ASSERT_EQUAL(SDO_MODE_SEGMENTED, ev->u.sdo_cli.mode);
	TEST_ASSERT_EQUAL_MEMORY(FX_DEVICE_NAME, big_out, 27);
	roundtrip(FX_IDX_DOMAIN, 4096, SDO_MODE_AUTO);
	ev = upload(FX_IDX_DOMAIN, big_out, FX_DOMAIN_MAX, SDO_MODE_AUTO, 4096);
	TEST_ASSERT_EQUAL(SDO_MODE_BLOCK, ev->u.sdo_cli.mode);
	TEST_ASSERT_EQUAL_MEMORY(big_in, big_out, 4096);
}

static void test_two_client_channels_two_servers(void)
{
	/* A second server node on the same bus; both client channels run
	 * at once, each to its own node. */
	co_node_config cfg = { .node_id = 6 };
	tb_port *srv2 = tb_add_node(&bus, &cfg, fx_od_new());
	sdo_client_req a = {
		.node_id = SRV_ID, .index = FX_IDX_DOMAIN, .data = big_in, .size = 3000, .tag = 1
	};
	sdo_client_req b = { .node_id = 6,
			     .index = FX_IDX_DOMAIN,
			     .data = big_in + 1,
			     .size = 2000,
			     .tag = 2,
			     .mode = SDO_MODE_SEGMENTED };

	TEST_ASSERT_NOT_NULL(srv2);
	TEST_ASSERT_EQUAL(0, sdo_client_submit(cli->node, 0, &a, bus.now));
	TEST_ASSERT_EQUAL(0, sdo_client_submit(cli->node, 1, &b, bus.now));
	TEST_ASSERT_EQUAL(1, sdo_client_pending(cli->node, 0));
	TEST_ASSERT_EQUAL(1, sdo_client_pending(cli->node, 1));
	tb_settle(&bus, 10000000);
	TEST_ASSERT_EQUAL(2, tb_event_count(cli, CO_EV_SDO_CLIENT_DONE));
	TEST_ASSERT_EQUAL_MEMORY(big_in, co_od_find(srv->od, FX_IDX_DOMAIN, 0)->data, 3000);
	TEST_ASSERT_EQUAL_MEMORY(big_in + 1, co_od_find(srv2->od, FX_IDX_DOMAIN, 0)->data, 2000);
	uint32_t v;
	TEST_ASSERT_EQUAL(0, co_od_get_u32(cli->od, 0x1281, 1, &v));
	TEST_ASSERT_EQUAL_HEX32(0x606, v);
	TEST_ASSERT_EQUAL(0, co_od_get_u32(cli->od, 0x1281, 2, &v));
	TEST_ASSERT_EQUAL_HEX32(0x586, v);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_matrix_domain_in_place);
	RUN_TEST(test_matrix_octet_string_staged);
	RUN_TEST(test_numeric_values_and_remote_aborts);
	RUN_TEST(test_block_1k_lost_and_repeated);
	RUN_TEST(test_block_duplicate_sub_block_end_and_last_segment);
	RUN_TEST(test_block_100k_lost_and_repeated);
	RUN_TEST(test_block_100k_clean_and_segmented);
	RUN_TEST(test_streaming_domains);
	RUN_TEST(test_streaming_callback_failure_aborts);
	RUN_TEST(test_fallback_block_to_segmented);
	RUN_TEST(test_auto_upload_block_with_protocol_switch);
	RUN_TEST(test_two_client_channels_two_servers);
	return UNITY_END();
}
