/* SPDX-License-Identifier: MIT */
/*
 * SDO client (CiA 301 §7.2.4). One state machine per channel, a bounded
 * FIFO of requests in front of it. States and their frame handlers are in
 * cli_states[]; all non-idle states share the per-frame timeout.
 *
 * Data never has to be in memory as a whole: downloads read the source
 * sequentially into one sub-block buffer (127 x 7 bytes), which is also
 * what a block retransmission resends; uploads hand each byte to the sink
 * exactly once, in order. The sub-block rules and the CRC are in
 * sdo_block.c, shared with the server.
 *
 * Requests reach a channel from its own FIFO (sdo_client_submit) or from
 * the pool FIFO shared by all channels (sdo_client_pool_submit). Whenever
 * a transfer ends, kick_all() starts what can start: first each idle
 * channel's own FIFO, then pool requests in order on channels that are
 * idle with an empty FIFO, skipping those whose target is busy. Every
 * transfer ends in complete() (or finish_unstarted() for a request
 * cancelled before it started): the request's con, then the event.
 */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "core/co_internal.h"
#include "core/nmt.h"
#include "core/sdo_block.h"
#include "core/sdo_client.h"

#define SUB_BLOCK_BYTES (SDO_BLK_MAX_SEQ * SDO_SEG_DATA) /* 889 */
#define UNKNOWN_SIZE UINT32_MAX

enum cli_state {
	CS_IDLE,
	CS_DN_INIT,     /* initiate download sent */
	CS_DN_SEG,      /* download segment sent */
	CS_UP_INIT,     /* initiate upload sent */
	CS_UP_SEG,      /* upload segment request sent */
	CS_BLK_DN_INIT, /* block download initiate sent */
	CS_BLK_DN_ACK,  /* sub-block sent, waiting for the ack */
	CS_BLK_DN_END,  /* end sent */
	CS_BLK_UP_INIT, /* block upload initiate sent */
	CS_BLK_UP_SUB,  /* receiving sub-block segments */
	CS_BLK_UP_END,  /* last sub-block acked, waiting for the end */
	CS_START_FAILED, /* could not start: completes at the next tick with
	                  * start_abort (never inside the submitting call) */
	CS_LEASED,      /* lent out raw (CiA 302-7 relay): frames go to lease_fn */
	CS_COUNT
};

struct cli_chan {
	struct sdo_client *cli;
	uint8_t num;
	uint8_t state;
	int rx_handle;
	uint64_t deadline;
	uint64_t timeout_us;

	/* queue: ring of cfg.sdo_client_queue_len waiting requests */
	sdo_client_req *q;
	uint16_t q_head;
	uint16_t q_len;

	sdo_client_req cur; /* the running request (valid if state != IDLE) */
	uint32_t cob_req;
	uint32_t cob_resp;
	uint8_t mode;
	bool fell_back;
	uint8_t toggle;
	uint32_t offset; /* bytes confirmed (download) / delivered (upload) */
	uint32_t total;  /* download: size; upload: indicated or UNKNOWN */
	uint32_t read_off; /* download: bytes taken from the source */
	uint32_t start_abort; /* CS_START_FAILED: the abort to report */

	/* block */
	struct sdo_blk_rx brx; /* upload: sequence, duplicates, CRC */
	struct sdo_blk_tx btx; /* download: sub-block, CRC */
	bool pend_valid;   /* upload: held-back segment (its length is only
	                    * known at the end request) */
	uint8_t pend[SDO_SEG_DATA];
	uint32_t sub_len;  /* download: bytes in sub_buf */
	uint8_t sub_buf[SUB_BLOCK_BYTES];

	sdo_client_raw_fn lease_fn; /* CS_LEASED */
	void *lease_arg;

	co_od_entry *od_cob[2]; /* 1280h+n sub 1/2 */
	co_od_entry *od_node;   /* sub 3 */

	/* `ended`: the last transfer this channel ended with its own abort
	 * frame (cancel, timeout, protocol error). The server may have sent
	 * more frames of it before it saw the abort; the next transfer to
	 * the same server (on any channel) takes it as its `filter` and
	 * ignores those frames until its own first answer arrives (see
	 * is_stale()). */
	struct stale_xfer {
		bool valid;
		bool upload;
		uint8_t mode;
		uint16_t index;
		uint8_t sub;
		uint32_t cob_resp;
	} ended, filter;
};

struct sdo_client {
	co_node *node;
	uint8_t n;
	/* pool: ring of cfg.sdo_client_pool_len requests waiting for any
	 * channel */
	sdo_client_req *pool;
	uint16_t pool_head;
	uint16_t pool_len;
	struct cli_chan ch[];
};

typedef void (*cli_frame_fn)(struct cli_chan *ch, const uint8_t *d);

static void st_ignore(struct cli_chan *ch, const uint8_t *d);
static void st_dn_init(struct cli_chan *ch, const uint8_t *d);
static void st_dn_seg(struct cli_chan *ch, const uint8_t *d);
static void st_up_init(struct cli_chan *ch, const uint8_t *d);
static void st_up_seg(struct cli_chan *ch, const uint8_t *d);
static void st_blk_dn_init(struct cli_chan *ch, const uint8_t *d);
static void st_blk_dn_ack(struct cli_chan *ch, const uint8_t *d);
static void st_blk_dn_end(struct cli_chan *ch, const uint8_t *d);
static void st_blk_up_init(struct cli_chan *ch, const uint8_t *d);
static void st_blk_up_sub(struct cli_chan *ch, const uint8_t *d);
static void st_blk_up_end(struct cli_chan *ch, const uint8_t *d);

static const struct {
	const char *name;
	cli_frame_fn on_frame;
} cli_states[CS_COUNT] = {
	[CS_IDLE] = { "idle", st_ignore },
	[CS_DN_INIT] = { "download initiate", st_dn_init },
	[CS_DN_SEG] = { "download segment", st_dn_seg },
	[CS_UP_INIT] = { "upload initiate", st_up_init },
	[CS_UP_SEG] = { "upload segment", st_up_seg },
	[CS_BLK_DN_INIT] = { "block download initiate", st_blk_dn_init },
	[CS_BLK_DN_ACK] = { "block download ack", st_blk_dn_ack },
	[CS_BLK_DN_END] = { "block download end", st_blk_dn_end },
	[CS_BLK_UP_INIT] = { "block upload initiate", st_blk_up_init },
	[CS_BLK_UP_SUB] = { "block upload sub-block", st_blk_up_sub },
	[CS_BLK_UP_END] = { "block upload end", st_blk_up_end },
	[CS_START_FAILED] = { "start failed", st_ignore },
	[CS_LEASED] = { "leased", st_ignore },
};

static void kick_all(struct sdo_client *cli);

/* ---- helpers ------------------------------------------------------------ */

static co_node *node_of(const struct cli_chan *ch)
{
	return ch->cli->node;
}

static void arm(struct cli_chan *ch)
{
	co_node *node = node_of(ch);

	ch->deadline = node->now_us + ch->timeout_us;
	co_node_deadline_lower(node, ch->deadline);
}

static void enter(struct cli_chan *ch, uint8_t state)
{
	ch->state = state;
	arm(ch);
}

static void tx(struct cli_chan *ch, const uint8_t d[8])
{
	co_frame f;

	co_frame_init(&f, ch->cob_req & CO_FRAME_EFF_MASK, 8);
	if (ch->cob_req & SDO_COB_EXT)
		f.flags |= CO_FRAME_EXT;
	memcpy(f.data, d, 8);
	co_node_send(node_of(ch), &f);
}

/* A frame with index/sub in bytes 1..3 and a 32-bit value in 4..7. */
static void tx_mux(struct cli_chan *ch, uint8_t cmd, uint32_t v)
{
	uint8_t d[8] = { cmd };

	co_put_le16(&d[1], ch->cur.index);
	d[3] = ch->cur.sub;
	co_put_le32(&d[4], v);
	tx(ch, d);
}

static bool mux_matches(const struct cli_chan *ch, const uint8_t *d)
{
	return co_get_le16(&d[1]) == ch->cur.index && d[3] == ch->cur.sub;
}

/* The one way a request ends: its confirmation, then the event for
 * observers. The request is a copy: the channel may already run the next
 * one when con returns. */
static void confirm(co_node *node, const sdo_client_req *r, uint8_t channel, uint8_t mode,
		    uint32_t abort, uint32_t size)
{
	co_event ev = { .kind = CO_EV_SDO_CLIENT_DONE };

	ev.u.sdo_cli.channel = channel;
	ev.u.sdo_cli.upload = r->upload;
	ev.u.sdo_cli.node_id = r->node_id;
	ev.u.sdo_cli.mode = mode;
	ev.u.sdo_cli.index = r->index;
	ev.u.sdo_cli.sub = r->sub;
	ev.u.sdo_cli.abort = abort;
	ev.u.sdo_cli.size = size;
	ev.u.sdo_cli.tag = r->tag;
	ev.u.sdo_cli.data = r->upload ? r->buf : NULL;
	ev.now_us = node->now_us;
	if (r->con)
		r->con(r->con_arg, &ev.u.sdo_cli);
	co_node_emit(node, &ev);
}

static void complete(struct cli_chan *ch, uint32_t abort)
{
	sdo_client_req r = ch->cur;

	ch->state = CS_IDLE;
	ch->deadline = CO_NO_DEADLINE;
	co_rx_disable(node_of(ch), ch->rx_handle);
	confirm(node_of(ch), &r, ch->num, ch->mode, abort, ch->offset);
	kick_all(ch->cli);
}

/* A request that could not start: report it from the next tick, so that
 * no completion ever runs inside the call that submitted it. */
static void fail_start(struct cli_chan *ch, uint32_t abort)
{
	ch->state = CS_START_FAILED;
	ch->start_abort = abort;
	ch->deadline = node_of(ch)->now_us;
	co_node_deadline_lower(node_of(ch), ch->deadline);
}

static void abort_local(struct cli_chan *ch, uint32_t code)
{
	tx_mux(ch, SDO_CCS_ABORT << 5, code);
	ch->ended = (struct stale_xfer){ .valid = true, .upload = ch->cur.upload,
					  .mode = ch->mode, .index = ch->cur.index,
					  .sub = ch->cur.sub, .cob_resp = ch->cob_resp };
	complete(ch, code);
}

/* A late frame of the transfer that ch->filter describes, arriving before
 * the first answer of the current one? Those are the old transfer's
 * segments (or block acks / sub-block segments), or its initiate answer or
 * abort naming the old object. An initiate answer or abort naming the
 * current object is the current answer; anything else is judged as an
 * answer to the current request. */
static bool is_stale(const struct cli_chan *ch, const uint8_t *d)
{
	const struct stale_xfer *s = &ch->filter;
	uint8_t cs = SDO_CS(d[0]);
	bool names_cur = co_get_le16(&d[1]) == ch->cur.index && d[3] == ch->cur.sub;
	bool names_old = co_get_le16(&d[1]) == s->index && d[3] == s->sub;
	bool initiate_or_abort = cs == SDO_SCS_UP_INIT || cs == SDO_SCS_DN_INIT ||
				 cs == SDO_SCS_BLK_DN || cs == SDO_SCS_BLK_UP || cs == SDO_SCS_ABORT;

	if (!s->valid)
		return false;
	if (initiate_or_abort && names_cur)
		return false;
	if (initiate_or_abort && names_old)
		return true;
	switch (s->mode) {
	case SDO_MODE_SEGMENTED:
		return cs == (s->upload ? SDO_SCS_UP_SEG : SDO_SCS_DN_SEG);
	case SDO_MODE_BLOCK:
		/* block upload: sub-block segments carry any byte 0 */
		return s->upload || d[0] == ((SDO_SCS_BLK_DN << 5) | SDO_BLK_ACK) ||
		       d[0] == ((SDO_SCS_BLK_DN << 5) | SDO_BLK_END);
	default:
		return false;
	}
}

/* Take up to len bytes from the download source. */
static int src_read(struct cli_chan *ch, uint8_t *buf, uint32_t len)
{
	int got;

	if (len == 0)
		return 0;
	if (ch->cur.data) {
		memcpy(buf, ch->cur.data + ch->read_off, len);
		got = (int)len;
	} else {
		got = ch->cur.src(ch->cur.ctx, ch->read_off, buf, len);
		if (got < 0 || (uint32_t)got != len)
			return -1; /* the value must be exactly `size` long */
	}
	ch->read_off += len;
	return got;
}

/* Hand len upload bytes to the buffer or sink; 0 or an abort code. */
static uint32_t sink_put(struct cli_chan *ch, const uint8_t *data, uint32_t len)
{
	if (ch->total != UNKNOWN_SIZE && len > ch->total - ch->offset)
		return SDO_AB_TYPE_LEN;
	if (ch->cur.buf) {
		if (len > ch->cur.cap - ch->offset)
			return SDO_AB_NO_MEM;
		if (len)
			memcpy(ch->cur.buf + ch->offset, data, len);
	} else if (ch->cur.sink && len) {
		if (ch->cur.sink(ch->cur.ctx, ch->offset, data, len, ch->total) < 0)
			return SDO_AB_STORE;
	}
	ch->offset += len;
	return 0;
}

/* Server abort while waiting for an answer: maybe fall back from block. */
static bool is_abort(const uint8_t *d)
{
	return SDO_CS(d[0]) == SDO_SCS_ABORT;
}

/* ---- download ----------------------------------------------------------- */

static void dn_send_segment(struct cli_chan *ch)
{
	uint32_t left = ch->total - ch->offset;
	uint32_t len = left < SDO_SEG_DATA ? left : SDO_SEG_DATA;
	bool last = left <= SDO_SEG_DATA;
	uint8_t d[8] = { 0 };

	if (src_read(ch, &d[1], len) < 0) {
		abort_local(ch, SDO_AB_STORE);
		return;
	}
	d[0] = (uint8_t)((SDO_CCS_DN_SEG << 5) | ch->toggle | ((SDO_SEG_DATA - len) << 1) |
			 (last ? SDO_SEG_LAST : 0));
	tx(ch, d);
	enter(ch, CS_DN_SEG);
}

static void start_download(struct cli_chan *ch)
{
	uint32_t size = ch->total;

	if (ch->mode == SDO_MODE_EXPEDITED) {
		uint8_t d[8] = { 0 };
		d[0] = (uint8_t)((SDO_CCS_DN_INIT << 5) | ((4u - size) << 2) | SDO_EXPEDITED |
				 SDO_SIZE_IND);
		co_put_le16(&d[1], ch->cur.index);
		d[3] = ch->cur.sub;
		if (src_read(ch, &d[4], size) < 0) {
			fail_start(ch, SDO_AB_STORE);
			return;
		}
		tx(ch, d);
		enter(ch, CS_DN_INIT);
	} else if (ch->mode == SDO_MODE_BLOCK) {
		ch->sub_len = 0;
		tx_mux(ch, (SDO_CCS_BLK_DN << 5) | SDO_BLK_CRC | SDO_BLK_SIZE_IND, size);
		enter(ch, CS_BLK_DN_INIT);
	} else {
		tx_mux(ch, (SDO_CCS_DN_INIT << 5) | SDO_SIZE_IND, size);
		enter(ch, CS_DN_INIT);
	}
}

static void st_dn_init(struct cli_chan *ch, const uint8_t *d)
{
	if (d[0] != (SDO_SCS_DN_INIT << 5)) {
		abort_local(ch, SDO_AB_CMD);
		return;
	}
	if (!mux_matches(ch, d)) {
		abort_local(ch, SDO_AB_PARAM_INCOMPAT);
		return;
	}
	if (ch->mode == SDO_MODE_EXPEDITED) {
		ch->offset = ch->total;
		complete(ch, 0);
		return;
	}
	dn_send_segment(ch);
}

static void st_dn_seg(struct cli_chan *ch, const uint8_t *d)
{
	if (SDO_CS(d[0]) != SDO_SCS_DN_SEG) {
		abort_local(ch, SDO_AB_CMD);
		return;
	}
	if ((d[0] & SDO_TOGGLE) != ch->toggle) {
		abort_local(ch, SDO_AB_TOGGLE);
		return;
	}
	ch->offset = ch->read_off;
	if (ch->offset >= ch->total) {
		complete(ch, 0);
		return;
	}
	ch->toggle ^= SDO_TOGGLE;
	dn_send_segment(ch);
}

/* ---- block download ------------------------------------------------------ */

/* Top the sub-block buffer up to blksize segments from the source. */
static bool blk_fill(struct cli_chan *ch)
{
	uint32_t cap = (uint32_t)ch->btx.blksize * SDO_SEG_DATA;
	uint32_t want;

	if (ch->sub_len >= cap)
		return true;
	want = cap - ch->sub_len;
	if (want > ch->total - ch->read_off)
		want = ch->total - ch->read_off;
	if (want == 0)
		return true;
	if (src_read(ch, ch->sub_buf + ch->sub_len, want) < 0)
		return false;
	ch->sub_len += want;
	return true;
}

static void blk_dn_send(struct cli_chan *ch)
{
	uint8_t segs;
	uint8_t d[8];

	if (!blk_fill(ch)) {
		abort_local(ch, SDO_AB_STORE);
		return;
	}
	segs = sdo_blk_tx_sub_block(&ch->btx, ch->sub_len, ch->read_off == ch->total);
	for (uint8_t seq = 1; seq <= segs; seq++) {
		sdo_blk_tx_segment(&ch->btx, seq, ch->sub_buf, d);
		tx(ch, d);
	}
	enter(ch, CS_BLK_DN_ACK);
}

static void st_blk_dn_init(struct cli_chan *ch, const uint8_t *d)
{
	if ((d[0] & 0xE3u) != (SDO_SCS_BLK_DN << 5 | SDO_BLK_INIT)) {
		abort_local(ch, SDO_AB_CMD);
		return;
	}
	if (!mux_matches(ch, d)) {
		abort_local(ch, SDO_AB_PARAM_INCOMPAT);
		return;
	}
	if (!sdo_blk_size_valid(d[4])) {
		abort_local(ch, SDO_AB_BLK_SIZE);
		return;
	}
	/* we asked for CRC; the server decides */
	sdo_blk_tx_start(&ch->btx, d[4], d[0] & SDO_BLK_CRC);
	blk_dn_send(ch);
}

static void st_blk_dn_ack(struct cli_chan *ch, const uint8_t *d)
{
	uint32_t acked;
	bool done;
	uint32_t ab = sdo_blk_tx_ack(&ch->btx, d, ch->sub_buf, &acked, &done);

	if (ab) {
		abort_local(ch, ab);
		return;
	}
	if (done) {
		uint8_t e[8];
		ch->offset = ch->total;
		sdo_blk_tx_end(&ch->btx, e);
		tx(ch, e);
		enter(ch, CS_BLK_DN_END);
		return;
	}
	/* Keep what was not acknowledged; it goes out again first. */
	memmove(ch->sub_buf, ch->sub_buf + acked, ch->sub_len - acked);
	ch->sub_len -= acked;
	ch->offset += acked;
	blk_dn_send(ch);
}

static void st_blk_dn_end(struct cli_chan *ch, const uint8_t *d)
{
	if (d[0] != ((SDO_SCS_BLK_DN << 5) | SDO_BLK_END)) {
		abort_local(ch, SDO_AB_CMD);
		return;
	}
	complete(ch, 0);
}

/* ---- upload ------------------------------------------------------------- */

static void up_request_segment(struct cli_chan *ch)
{
	uint8_t d[8] = { (uint8_t)((SDO_CCS_UP_SEG << 5) | ch->toggle) };

	tx(ch, d);
	enter(ch, CS_UP_SEG);
}

static void start_upload(struct cli_chan *ch)
{
	ch->total = UNKNOWN_SIZE;
	if (ch->mode == SDO_MODE_BLOCK) {
		const co_node_config *c = &node_of(ch)->cfg;
		uint8_t d[8] = { (SDO_CCS_BLK_UP << 5) | SDO_BLK_CRC | SDO_BLK_INIT };
		uint32_t pst = 0;
		if (ch->cur.mode == SDO_MODE_AUTO)
			pst = c->sdo_client_block_threshold - 1;
		co_put_le16(&d[1], ch->cur.index);
		d[3] = ch->cur.sub;
		d[4] = c->sdo_client_blksize;
		d[5] = (uint8_t)(pst > 255 ? 255 : pst);
		ch->brx.blksize = c->sdo_client_blksize;
		tx(ch, d);
		enter(ch, CS_BLK_UP_INIT);
		return;
	}
	tx_mux(ch, SDO_CCS_UP_INIT << 5, 0);
	enter(ch, CS_UP_INIT);
}

/* Initiate upload response (also the answer to a block upload initiate
 * when the server applies the protocol switch threshold). */
static void up_init_resp(struct cli_chan *ch, const uint8_t *d)
{
	uint32_t ab;

	if (d[0] & SDO_EXPEDITED) {
		uint32_t len = (d[0] & SDO_SIZE_IND) ? 4u - ((d[0] >> 2) & 3u) : 4u;
		ch->mode = SDO_MODE_EXPEDITED;
		ab = sink_put(ch, &d[4], len);
		if (ab)
			abort_local(ch, ab);
		else
			complete(ch, 0);
		return;
	}
	ch->mode = SDO_MODE_SEGMENTED;
	if (d[0] & SDO_SIZE_IND) {
		ch->total = co_get_le32(&d[4]);
		if (ch->cur.buf && ch->total > ch->cur.cap) {
			abort_local(ch, SDO_AB_NO_MEM);
			return;
		}
	}
	ch->toggle = 0;
	up_request_segment(ch);
}

static void st_up_init(struct cli_chan *ch, const uint8_t *d)
{
	if ((d[0] & 0xF0u) != (SDO_SCS_UP_INIT << 5)) {
		abort_local(ch, SDO_AB_CMD);
		return;
	}
	if (!mux_matches(ch, d)) {
		abort_local(ch, SDO_AB_PARAM_INCOMPAT);
		return;
	}
	up_init_resp(ch, d);
}

static void st_up_seg(struct cli_chan *ch, const uint8_t *d)
{
	uint32_t len = SDO_SEG_DATA - ((d[0] >> 1) & 7u);
	uint32_t ab;

	if (SDO_CS(d[0]) != SDO_SCS_UP_SEG) {
		abort_local(ch, SDO_AB_CMD);
		return;
	}
	if ((d[0] & SDO_TOGGLE) != ch->toggle) {
		abort_local(ch, SDO_AB_TOGGLE);
		return;
	}
	ab = sink_put(ch, &d[1], len);
	if (!ab && (d[0] & SDO_SEG_LAST) && ch->total != UNKNOWN_SIZE && ch->offset != ch->total)
		ab = SDO_AB_TYPE_LEN;
	if (ab) {
		abort_local(ch, ab);
		return;
	}
	if (d[0] & SDO_SEG_LAST) {
		complete(ch, 0);
		return;
	}
	ch->toggle ^= SDO_TOGGLE;
	up_request_segment(ch);
}

/* ---- block upload ------------------------------------------------------- */

static void st_blk_up_init(struct cli_chan *ch, const uint8_t *d)
{
	uint8_t start[8] = { (SDO_CCS_BLK_UP << 5) | SDO_BLK_START };

	if (SDO_CS(d[0]) == SDO_SCS_UP_INIT) { /* protocol switch */
		if (mux_matches(ch, d))
			up_init_resp(ch, d);
		else
			abort_local(ch, SDO_AB_PARAM_INCOMPAT);
		return;
	}
	if ((d[0] & 0xE1u) != (SDO_SCS_BLK_UP << 5)) {
		abort_local(ch, SDO_AB_CMD);
		return;
	}
	if (!mux_matches(ch, d)) {
		abort_local(ch, SDO_AB_PARAM_INCOMPAT);
		return;
	}
	if (d[0] & SDO_BLK_SIZE_IND) {
		ch->total = co_get_le32(&d[4]);
		if (ch->cur.buf && ch->total > ch->cur.cap) {
			abort_local(ch, SDO_AB_NO_MEM);
			return;
		}
	}
	/* blksize: what start_upload() announced */
	sdo_blk_rx_start(&ch->brx, ch->brx.blksize, d[0] & SDO_BLK_CRC);
	ch->pend_valid = false;
	tx(ch, start);
	enter(ch, CS_BLK_UP_SUB);
}

static void blk_up_ack(struct cli_chan *ch)
{
	uint8_t d[8];

	sdo_blk_rx_ack(&ch->brx, d);
	tx(ch, d);
	enter(ch, ch->brx.last_seen ? CS_BLK_UP_END : CS_BLK_UP_SUB);
}

/* Sequence rules, duplicates and CRC: sdo_block.c, as for the server's
 * block download. Each segment is held back until the next one arrives:
 * the sink must only see data bytes, and the last segment's length is
 * only known at the end request. */
static void st_blk_up_sub(struct cli_chan *ch, const uint8_t *d)
{
	unsigned act = sdo_blk_rx_segment(&ch->brx, d);

	if (act & SDO_BLK_RX_BAD_SEQ) {
		abort_local(ch, SDO_AB_SEQ);
		return;
	}
	if (act & SDO_BLK_RX_STORE) {
		if (ch->pend_valid) {
			uint32_t ab = sink_put(ch, ch->pend, SDO_SEG_DATA);
			if (ab) {
				abort_local(ch, ab);
				return;
			}
		}
		memcpy(ch->pend, &d[1], SDO_SEG_DATA);
		ch->pend_valid = true;
	}
	if (act & SDO_BLK_RX_ACK)
		blk_up_ack(ch);
	else
		arm(ch);
}

static void st_blk_up_end(struct cli_chan *ch, const uint8_t *d)
{
	uint8_t resp[8] = { (SDO_CCS_BLK_UP << 5) | SDO_BLK_END };
	uint32_t last_len;
	uint32_t ab = 0;

	if (sdo_blk_rx_is_dup(&ch->brx, d)) {
		arm(ch);
		return;
	}
	if (!sdo_blk_rx_end(d, &last_len)) {
		abort_local(ch, SDO_AB_CMD);
		return;
	}
	if (ch->pend_valid)
		ab = sink_put(ch, ch->pend, last_len);
	if (!ab && ch->total != UNKNOWN_SIZE && ch->offset != ch->total)
		ab = SDO_AB_TYPE_LEN;
	if (!ab && !sdo_blk_rx_crc_ok(&ch->brx, d, last_len))
		ab = SDO_AB_CRC;
	if (ab) {
		abort_local(ch, ab);
		return;
	}
	tx(ch, resp);
	complete(ch, 0);
}

static void st_ignore(struct cli_chan *ch, const uint8_t *d)
{
	(void)ch;
	(void)d;
}

/* ---- receive, start, queue ------------------------------------------------ */

static void restart_without_block(struct cli_chan *ch)
{
	ch->fell_back = true;
	ch->offset = ch->read_off = 0;
	ch->mode = ch->cur.upload ? SDO_MODE_SEGMENTED
		   : (ch->total >= 1 && ch->total <= SDO_EXP_DATA) ? SDO_MODE_EXPEDITED
								     : SDO_MODE_SEGMENTED;
	if (ch->cur.upload)
		start_upload(ch);
	else
		start_download(ch);
}

static void cli_rx(co_node *node, void *arg, const co_frame *f, uint64_t now_us)
{
	struct cli_chan *ch = arg;
	const uint8_t *d = f->data;

	(void)node;
	if (ch->state == CS_IDLE || ch->state == CS_START_FAILED || f->len != 8 ||
	    (f->flags & CO_FRAME_RTR))
		return;
	if (ch->state == CS_LEASED) {
		ch->lease_fn(ch->lease_arg, d, now_us);
		return;
	}
	if (is_stale(ch, d))
		return;
	ch->filter.valid = false; /* the server answers the current request */
	if (ch->state == CS_BLK_UP_SUB ? sdo_blk_seg_is_abort(d)
				       : is_abort(d) && !sdo_blk_rx_is_dup(&ch->brx, d)) {
		uint32_t code = co_get_le32(&d[4]);
		bool refused = code == SDO_AB_CMD || code == SDO_AB_UNSUPP_ACCESS;
		if (refused && !ch->fell_back &&
		    (ch->state == CS_BLK_DN_INIT || ch->state == CS_BLK_UP_INIT)) {
			restart_without_block(ch);
			return;
		}
		complete(ch, code);
		return;
	}
	cli_states[ch->state].on_frame(ch, d);
}

static uint8_t pick_mode(const struct cli_chan *ch, const sdo_client_req *r)
{
	uint32_t thr = node_of(ch)->cfg.sdo_client_block_threshold;

	if (r->upload) {
		if (r->mode == SDO_MODE_BLOCK || (r->mode == SDO_MODE_AUTO && r->size >= thr))
			return SDO_MODE_BLOCK;
		return SDO_MODE_SEGMENTED;
	}
	switch (r->mode) {
	case SDO_MODE_BLOCK: return SDO_MODE_BLOCK;
	case SDO_MODE_SEGMENTED: return SDO_MODE_SEGMENTED;
	case SDO_MODE_EXPEDITED:
		return r->size >= 1 && r->size <= 4 ? SDO_MODE_EXPEDITED : SDO_MODE_SEGMENTED;
	default:
		if (r->size >= 1 && r->size <= 4)
			return SDO_MODE_EXPEDITED;
		return r->size >= thr ? SDO_MODE_BLOCK : SDO_MODE_SEGMENTED;
	}
}

static uint32_t req_cob_req(const sdo_client_req *r)
{
	return r->cob_req ? r->cob_req : SDO_COB_RX_BASE + r->node_id;
}

static uint32_t req_cob_resp(const sdo_client_req *r)
{
	return r->cob_resp ? r->cob_resp : SDO_COB_TX_BASE + r->node_id;
}

/* Another channel is talking to the same server right now? */
static bool target_busy(const struct sdo_client *cli, const struct cli_chan *self, uint32_t resp)
{
	for (uint8_t i = 0; i < cli->n; i++) {
		const struct cli_chan *o = &cli->ch[i];
		if (o != self && o->state != CS_IDLE && o->cob_resp == resp)
			return true;
	}
	return false;
}

static void start(struct cli_chan *ch, const sdo_client_req *r)
{
	co_node *node = node_of(ch);

	ch->cur = *r;
	ch->cob_req = req_cob_req(r);
	ch->cob_resp = req_cob_resp(r);
	/* Late frames of a transfer to this server that some channel ended
	 * with an abort frame are to be ignored (is_stale()). */
	ch->filter.valid = false;
	for (uint8_t i = 0; i < ch->cli->n; i++) {
		struct stale_xfer *st = &ch->cli->ch[i].ended;
		if (st->valid && st->cob_resp == ch->cob_resp) {
			ch->filter = *st;
			st->valid = false;
		}
	}
	ch->timeout_us = (uint64_t)(r->timeout_ms ? r->timeout_ms : node->cfg.sdo_client_timeout_ms) * 1000u;
	ch->mode = pick_mode(ch, r);
	ch->fell_back = false;
	sdo_blk_rx_reset(&ch->brx);
	ch->offset = ch->read_off = 0;
	ch->toggle = 0;
	ch->total = r->upload ? UNKNOWN_SIZE : r->size;
	/* 1280h+n shows the current target, as a manager would set it. */
	if (ch->od_cob[0])
		co_od_entry_set_raw(ch->od_cob[0], ch->cob_req);
	if (ch->od_cob[1])
		co_od_entry_set_raw(ch->od_cob[1], ch->cob_resp);
	if (ch->od_node)
		co_od_entry_set_raw(ch->od_node, r->node_id);
	/* CiA 301 §7.3.2.2: no SDO in STOPPED; reported from the next tick
	 * like any request that cannot start. */
	if (co_nmt_get_state(node) == CO_NMT_STOPPED) {
		fail_start(ch, SDO_AB_DEV_STATE);
		return;
	}
	if (co_rx_move(node, ch->rx_handle, ch->cob_resp & CO_FRAME_EFF_MASK,
		       (ch->cob_resp & SDO_COB_EXT) ? CO_FRAME_EXT : 0) != 0) {
		fail_start(ch, SDO_AB_NO_RESOURCE);
		return;
	}
	if (r->upload)
		start_upload(ch);
	else
		start_download(ch);
}

/* Start the head of the queue if the channel is idle and the target free. */
static void kick(struct cli_chan *ch)
{
	const sdo_client_req *r;

	if (ch->state != CS_IDLE || ch->q_len == 0)
		return;
	r = &ch->q[ch->q_head];
	if (target_busy(ch->cli, ch, req_cob_resp(r)))
		return;
	sdo_client_req tmp = *r;
	ch->q_head = (uint16_t)((ch->q_head + 1) % node_of(ch)->cfg.sdo_client_queue_len);
	ch->q_len--;
	start(ch, &tmp);
}

/* Free for the pool: idle, and nothing waiting in its own FIFO. */
static struct cli_chan *free_channel(struct sdo_client *cli)
{
	for (uint8_t i = 0; i < cli->n; i++)
		if (cli->ch[i].state == CS_IDLE && cli->ch[i].q_len == 0)
			return &cli->ch[i];
	return NULL;
}

static sdo_client_req *pool_at(struct sdo_client *cli, uint16_t i)
{
	return &cli->pool[(cli->pool_head + i) % cli->node->cfg.sdo_client_pool_len];
}

static void pool_remove(struct sdo_client *cli, uint16_t i)
{
	if (i == 0) { /* the usual case: the oldest starts */
		cli->pool_head = (uint16_t)((cli->pool_head + 1) % cli->node->cfg.sdo_client_pool_len);
		cli->pool_len--;
		return;
	}
	for (uint16_t j = i; j + 1 < cli->pool_len; j++)
		*pool_at(cli, j) = *pool_at(cli, (uint16_t)(j + 1));
	cli->pool_len--;
}

/* Start waiting pool requests, oldest first, on free channels. One whose
 * target is busy stays (and so do the later ones for that target, which
 * see the same busy target: per-target order holds). */
static void pool_kick(struct sdo_client *cli)
{
	uint16_t i = 0;

	while (i < cli->pool_len) {
		const sdo_client_req *r = pool_at(cli, i);
		struct cli_chan *ch;

		if (target_busy(cli, NULL, req_cob_resp(r))) {
			i++;
			continue;
		}
		ch = free_channel(cli);
		if (!ch)
			return;
		sdo_client_req tmp = *r;
		pool_remove(cli, i);
		start(ch, &tmp);
	}
}

static void kick_all(struct sdo_client *cli)
{
	for (uint8_t i = 0; i < cli->n; i++)
		kick(&cli->ch[i]);
	pool_kick(cli);
}

static bool req_valid(const sdo_client_req *r)
{
	bool explicit_cob = r->cob_req && r->cob_resp;

	if (!explicit_cob && (r->node_id < 1 || r->node_id > 127))
		return false;
	if (r->mode > SDO_MODE_BLOCK)
		return false;
	if (!r->upload && r->size && !r->data && !r->src)
		return false;
	if (r->upload && r->buf && r->cap == 0 && r->size)
		return false;
	return true;
}

int sdo_client_submit(co_node *node, uint8_t channel, const sdo_client_req *req, uint64_t now_us)
{
	struct sdo_client *cli = node->sdo_cli;
	struct cli_chan *ch;
	uint16_t cap;

	if (!cli || channel >= cli->n || !req || !req_valid(req))
		return -EINVAL;
	ch = &cli->ch[channel];
	cap = node->cfg.sdo_client_queue_len;
	if (ch->q_len >= cap)
		return -ENOSPC;
	node->now_us = now_us;
	ch->q[(ch->q_head + ch->q_len) % cap] = *req;
	ch->q_len++;
	kick(ch);
	return 0;
}

int sdo_client_read(co_node *node, uint8_t channel, uint8_t node_id, uint16_t index,
		    uint8_t sub, uint8_t *buf, uint32_t cap, uint32_t timeout_ms,
		    uint64_t tag, uint64_t now_us)
{
	sdo_client_req r = { .upload = true, .node_id = node_id, .index = index,
			     .sub = sub, .timeout_ms = timeout_ms, .tag = tag,
			     .buf = buf, .cap = cap };
	return sdo_client_submit(node, channel, &r, now_us);
}

int sdo_client_write(co_node *node, uint8_t channel, uint8_t node_id, uint16_t index,
		     uint8_t sub, const uint8_t *data, uint32_t size, uint32_t timeout_ms,
		     uint64_t tag, uint64_t now_us)
{
	sdo_client_req r = { .upload = false, .node_id = node_id, .index = index,
			     .sub = sub, .timeout_ms = timeout_ms, .tag = tag,
			     .data = data, .size = size };
	return sdo_client_submit(node, channel, &r, now_us);
}

/* Running on ch with this tag: abort it (an abort frame unless it never
 * got on the wire). */
static bool cancel_running(struct cli_chan *ch, uint64_t tag, uint32_t abort)
{
	if (ch->state == CS_IDLE || ch->state == CS_LEASED || ch->cur.tag != tag)
		return false;
	if (ch->state == CS_START_FAILED)
		complete(ch, abort);
	else
		abort_local(ch, abort);
	return true;
}

/* Waiting in ch's own FIFO with this tag: remove it and confirm it. */
static bool cancel_queued(struct cli_chan *ch, uint64_t tag, uint32_t abort)
{
	uint16_t cap = node_of(ch)->cfg.sdo_client_queue_len;

	for (uint16_t i = 0; i < ch->q_len; i++) {
		uint16_t pos = (uint16_t)((ch->q_head + i) % cap);
		if (ch->q[pos].tag != tag)
			continue;
		sdo_client_req r = ch->q[pos];
		for (uint16_t j = i; j + 1 < ch->q_len; j++)
			ch->q[(ch->q_head + j) % cap] = ch->q[(ch->q_head + j + 1) % cap];
		ch->q_len--;
		confirm(node_of(ch), &r, ch->num, r.mode, abort, 0);
		return true;
	}
	return false;
}

int sdo_client_cancel(co_node *node, uint8_t channel, uint64_t tag, uint32_t abort,
		      uint64_t now_us)
{
	struct sdo_client *cli = node->sdo_cli;

	if (!cli || channel >= cli->n)
		return -EINVAL;
	node->now_us = now_us;
	if (cancel_running(&cli->ch[channel], tag, abort) ||
	    cancel_queued(&cli->ch[channel], tag, abort))
		return 0;
	return -ENOENT;
}

int sdo_client_cancel_tag(co_node *node, uint64_t tag, uint32_t abort, uint64_t now_us)
{
	struct sdo_client *cli = node->sdo_cli;

	if (!cli)
		return -ENOENT;
	node->now_us = now_us;
	for (uint8_t i = 0; i < cli->n; i++)
		if (cancel_running(&cli->ch[i], tag, abort))
			return 0;
	for (uint8_t i = 0; i < cli->n; i++)
		if (cancel_queued(&cli->ch[i], tag, abort))
			return 0;
	for (uint16_t i = 0; i < cli->pool_len; i++) {
		if (pool_at(cli, i)->tag != tag)
			continue;
		sdo_client_req r = *pool_at(cli, i);
		pool_remove(cli, i);
		confirm(node, &r, SDO_CLIENT_NO_CHANNEL, r.mode, abort, 0);
		return 0;
	}
	return -ENOENT;
}

int sdo_client_pool_submit(co_node *node, const sdo_client_req *req, uint64_t now_us)
{
	struct sdo_client *cli = node->sdo_cli;

	if (!cli || !req || !req_valid(req))
		return -EINVAL;
	node->now_us = now_us;
	if (req->no_wait) {
		struct cli_chan *ch = free_channel(cli);
		if (!ch || target_busy(cli, NULL, req_cob_resp(req)))
			return -EBUSY;
		start(ch, req);
		return 0;
	}
	if (cli->pool_len >= node->cfg.sdo_client_pool_len)
		return -ENOSPC;
	*pool_at(cli, cli->pool_len) = *req;
	cli->pool_len++;
	pool_kick(cli);
	return 0;
}

/* ---- relay lease (CiA 302-7) ------------------------------------------------ */

int sdo_client_lease(co_node *node, uint8_t node_id, uint32_t cob_req, uint32_t cob_resp,
		     sdo_client_raw_fn fn, void *arg, uint64_t now_us)
{
	struct sdo_client *cli = node->sdo_cli;
	sdo_client_req r = { .node_id = node_id, .cob_req = cob_req, .cob_resp = cob_resp };
	struct cli_chan *ch;

	if (!cli || !fn || node_id < 1 || node_id > 127)
		return -EINVAL;
	node->now_us = now_us;
	if (target_busy(cli, NULL, req_cob_resp(&r)))
		return -EALREADY;
	ch = free_channel(cli);
	if (!ch)
		return -EBUSY;
	if (co_rx_move(node, ch->rx_handle, req_cob_resp(&r) & CO_FRAME_EFF_MASK,
		       (req_cob_resp(&r) & SDO_COB_EXT) ? CO_FRAME_EXT : 0) != 0)
		return -ENOSPC;
	ch->cur = r;
	ch->cob_req = req_cob_req(&r);
	ch->cob_resp = req_cob_resp(&r);
	ch->lease_fn = fn;
	ch->lease_arg = arg;
	ch->state = CS_LEASED;
	ch->deadline = CO_NO_DEADLINE; /* the relay keeps its own timers */
	if (ch->od_cob[0])
		co_od_entry_set_raw(ch->od_cob[0], ch->cob_req);
	if (ch->od_cob[1])
		co_od_entry_set_raw(ch->od_cob[1], ch->cob_resp);
	if (ch->od_node)
		co_od_entry_set_raw(ch->od_node, node_id);
	return ch->num;
}

static struct cli_chan *leased(co_node *node, uint8_t channel)
{
	struct sdo_client *cli = node->sdo_cli;

	if (!cli || channel >= cli->n || cli->ch[channel].state != CS_LEASED)
		return NULL;
	return &cli->ch[channel];
}

int sdo_client_lease_send(co_node *node, uint8_t channel, const uint8_t d[8])
{
	struct cli_chan *ch = leased(node, channel);

	if (!ch)
		return -ENOENT;
	tx(ch, d);
	return 0;
}

int sdo_client_lease_end(co_node *node, uint8_t channel, uint64_t now_us)
{
	struct cli_chan *ch = leased(node, channel);

	if (!ch)
		return -ENOENT;
	node->now_us = now_us;
	ch->state = CS_IDLE;
	ch->lease_fn = NULL;
	co_rx_disable(node, ch->rx_handle);
	kick_all(ch->cli);
	return 0;
}

unsigned sdo_client_pool_waiting(const co_node *node)
{
	return node->sdo_cli ? node->sdo_cli->pool_len : 0;
}

unsigned sdo_client_pending(const co_node *node, uint8_t channel)
{
	const struct sdo_client *cli = node->sdo_cli;

	if (!cli || channel >= cli->n)
		return 0;
	return cli->ch[channel].q_len + (cli->ch[channel].state != CS_IDLE);
}

uint8_t sdo_client_channel_count(const co_node *node)
{
	return node->sdo_cli ? node->sdo_cli->n : 0;
}

/* ---- service ops -------------------------------------------------------- */

static int chan_od_init(struct cli_chan *ch)
{
	co_od *od = node_of(ch)->od;
	uint16_t idx = (uint16_t)(SDO_CLIENT_PARAM + ch->num);
	int rc = sdo_param_od_add(od, idx, CO_ACC_RO);

	ch->od_cob[0] = co_od_find(od, idx, 1);
	ch->od_cob[1] = co_od_find(od, idx, 2);
	ch->od_node = co_od_find(od, idx, 3);
	return rc;
}

static void cli_fini(co_node *node)
{
	struct sdo_client *cli = node->sdo_cli;

	if (!cli)
		return;
	for (uint8_t i = 0; i < cli->n; i++) {
		if (cli->ch[i].rx_handle >= 0)
			co_rx_unregister(node, cli->ch[i].rx_handle);
		free(cli->ch[i].q);
	}
	free(cli->pool);
	free(cli);
	node->sdo_cli = NULL;
}

static int cli_init(co_node *node)
{
	uint8_t n = node->cfg.sdo_client_count;
	struct sdo_client *cli;
	int rc = 0;

	if (n == 0)
		return 0;
	cli = calloc(1, sizeof(*cli) + n * sizeof(cli->ch[0]));
	if (!cli)
		return -ENOMEM;
	cli->node = node;
	cli->n = n;
	node->sdo_cli = cli;
	for (uint8_t i = 0; i < n; i++)
		cli->ch[i].rx_handle = -1;
	cli->pool = calloc(node->cfg.sdo_client_pool_len, sizeof(*cli->pool));
	if (!cli->pool)
		rc = -ENOMEM;
	for (uint8_t i = 0; i < n && !rc; i++) {
		struct cli_chan *ch = &cli->ch[i];
		ch->cli = cli;
		ch->num = i;
		ch->deadline = CO_NO_DEADLINE;
		ch->q = calloc(node->cfg.sdo_client_queue_len, sizeof(*ch->q));
		if (!ch->q) {
			rc = -ENOMEM;
			break;
		}
		ch->rx_handle = co_rx_register(node, 0, 0, cli_rx, ch);
		if (ch->rx_handle < 0) {
			rc = ch->rx_handle;
			break;
		}
		co_rx_disable(node, ch->rx_handle);
		rc = chan_od_init(ch);
	}
	if (rc)
		cli_fini(node);
	return rc;
}

static uint64_t cli_tick(co_node *node, uint64_t now_us)
{
	struct sdo_client *cli = node->sdo_cli;
	uint64_t next = CO_NO_DEADLINE;

	if (!cli)
		return next;
	for (uint8_t i = 0; i < cli->n; i++) {
		struct cli_chan *ch = &cli->ch[i];
		if (ch->state == CS_START_FAILED && now_us >= ch->deadline)
			complete(ch, ch->start_abort);
		else if (ch->state != CS_IDLE && now_us >= ch->deadline)
			abort_local(ch, SDO_AB_TIMEOUT);
	}
	/* A second pass: completions above may have started queued requests. */
	for (uint8_t i = 0; i < cli->n; i++)
		if (cli->ch[i].state != CS_IDLE && cli->ch[i].deadline < next)
			next = cli->ch[i].deadline;
	return next;
}

static void cli_reset_comm(co_node *node, uint64_t now_us)
{
	struct sdo_client *cli = node->sdo_cli;

	(void)now_us;
	if (!cli)
		return;
	/* Client parameters went back to defaults; running transfers stay
	 * (the manager's requests outlive our own reset communication) but
	 * the OD mirrors the current target again. */
	for (uint8_t i = 0; i < cli->n; i++) {
		struct cli_chan *ch = &cli->ch[i];
		if (ch->state == CS_IDLE)
			continue;
		if (ch->od_cob[0])
			co_od_entry_set_raw(ch->od_cob[0], ch->cob_req);
		if (ch->od_cob[1])
			co_od_entry_set_raw(ch->od_cob[1], ch->cob_resp);
		if (ch->od_node)
			co_od_entry_set_raw(ch->od_node, ch->cur.node_id);
	}
}

/* Entering STOPPED: running transfers end without a frame (no SDO traffic
 * in STOPPED) with 0x08000022 (device state); the requests that start
 * next fail the same way from the next tick (start()). */
static void cli_nmt_changed(co_node *node, uint8_t state, uint64_t now_us)
{
	struct sdo_client *cli = node->sdo_cli;

	(void)now_us;
	if (!cli || state != CO_NMT_STOPPED)
		return;
	for (uint8_t i = 0; i < cli->n; i++)
		if (cli->ch[i].state != CS_IDLE && cli->ch[i].state != CS_START_FAILED &&
		    cli->ch[i].state != CS_LEASED) /* a relay lease: its owner's business */
			complete(&cli->ch[i], SDO_AB_DEV_STATE);
}

const co_service co_svc_sdo_client = {
	.name = "sdo-client",
	.init = cli_init,
	.fini = cli_fini,
	.tick = cli_tick,
	.reset_comm = cli_reset_comm,
	.nmt_changed = cli_nmt_changed,
};
