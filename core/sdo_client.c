/* SPDX-License-Identifier: MIT */
/*
 * SDO client (CiA 301 §7.2.4). One core/fsm.h machine per channel, a
 * bounded FIFO of requests in front of it. The table cli_states[] gives
 * each state its frame handler, which returns the next state; all transfer
 * states share one on_enter (the per-frame timer) and one timeout rule.
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
 * transfer ends in complete(), which returns idle; idle's on_enter calls
 * the request's con, then emits the event (a request cancelled before it
 * started is confirmed directly).
 */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "core/co_internal.h"
#include "core/fsm.h"
#include "core/nmt.h"
#include "core/sdo_block.h"
#include "core/sdo_client.h"

#define SUB_BLOCK_BYTES (SDO_BLK_MAX_SEQ * SDO_SEG_DATA) /* 889 */
#define UNKNOWN_SIZE UINT32_MAX

enum cli_state {
	CS_IDLE,
	CS_DN_INIT,      /* initiate download sent */
	CS_DN_SEG,       /* download segment sent */
	CS_UP_INIT,      /* initiate upload sent */
	CS_UP_SEG,       /* upload segment request sent */
	CS_BLK_DN_INIT,  /* block download initiate sent */
	CS_BLK_DN_ACK,   /* sub-block sent, waiting for the ack */
	CS_BLK_DN_END,   /* end sent */
	CS_BLK_UP_INIT,  /* block upload initiate sent */
	CS_BLK_UP_SUB,   /* receiving sub-block segments */
	CS_BLK_UP_END,   /* last sub-block acked, waiting for the end */
	CS_START_FAILED, /* could not start: completes at the next tick with
	                  * start_abort (never inside the submitting call) */
	CS_LEASED,       /* lent out raw (CiA 302-7 relay): frames go to lease_fn */
	CS_COUNT
};

struct cli_chan {
	struct sdo_client *cli;
	uint8_t num;
	co_fsm fsm;          /* state: enum cli_state (cli_states[]) */
	bool done_pending;   /* the request ended: idle's on_enter confirms */
	uint32_t done_abort; /* ... with this abort code (0 = success) */
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
	uint32_t offset;      /* bytes confirmed (download) / delivered (upload) */
	uint32_t total;       /* download: size; upload: indicated or UNKNOWN */
	uint32_t read_off;    /* download: bytes taken from the source */
	uint32_t start_abort; /* CS_START_FAILED: the abort to report */
	bool answered;        /* a frame of the server for this request came */

	/* block */
	struct sdo_blk_rx brx; /* upload: sequence, duplicates, CRC */
	struct sdo_blk_tx btx; /* download: sub-block, CRC */
	bool pend_valid;       /* upload: held-back segment (its length is only
	                    * known at the end request) */
	uint8_t pend[SDO_SEG_DATA];
	uint32_t sub_len; /* download: bytes in sub_buf */
	uint8_t sub_buf[SUB_BLOCK_BYTES];

	sdo_client_raw_fn lease_fn; /* CS_LEASED */
	void *lease_arg;
	/* The gate does not offer it (sdo_client_set_gate): the node's own
	 * requests hold it, or a lease bound on it by sdo_client_lease_channel
	 * does; given back (FREE_CHANNEL) once it is idle with nothing queued. */
	bool gated_out;

	co_od_entry *od_cob[2]; /* 1280h+n sub 1/2 */
	co_od_entry *od_node;   /* sub 3 */

	/* `ended`: the last transfer this channel ended with its own abort
	 * frame (cancel, timeout, protocol error). The server may have sent
	 * more frames of it before it saw the abort; the next transfer to
	 * the same server (on any channel) takes it as its `filter` and
	 * ignores those frames until its own first answer arrives (see
	 * is_stale()). Also the last transfer it completed successfully
	 * (`answered`): another answer to that request, arriving within the
	 * timeout while the channel is idle or before the next transfer's
	 * first answer, comes from a second device on the server's node-ID
	 * (CO_EV_SDO_CLIENT_SECOND_ANSWER). */
	struct stale_xfer {
		bool valid;
		bool answered; /* it ended with the server's answer */
		/* the server had answered its initiate: what may still come
		 * are frames of its data phase, which is_stale() tells apart
		 * from the next transfer's answers */
		bool init_answered;
		bool upload;
		uint8_t mode;
		uint16_t index;
		uint8_t sub;
		uint32_t cob_resp;
		uint64_t at_us; /* when it ended (answered, or our abort) */
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
	/* the second user of the pool (sdo_client_set_gate) */
	sdo_client_gate_fn gate;
	void *gate_ctx;
	uint64_t srv_held[2]; /* servers (node-IDs) taken from the gate */
	uint64_t retry_us;    /* a refused request is tried again then */
	struct cli_chan ch[];
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

static int state_of(const struct cli_chan *ch)
{
	return co_fsm_state_of(&ch->fsm);
}

static void tx(struct cli_chan *ch, const uint8_t d[8])
{
	co_frame f;

	if (ch->cur.relay && state_of(ch) != CS_LEASED) {
		ch->cur.relay(ch->cur.relay_ctx, d);
		return;
	}
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
		    uint32_t abort, uint32_t size, bool answered)
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
	ev.u.sdo_cli.answered = answered;
	ev.now_us = node->now_us;
	if (r->con)
		r->con(r->con_arg, &ev.u.sdo_cli);
	co_node_emit(node, &ev);
}

/* The running request ends with `abort` (0 = success): back to idle,
 * whose on_enter confirms it and starts what waits. */
static int complete(struct cli_chan *ch, uint32_t abort)
{
	if (!abort)
		ch->ended = (struct stale_xfer){ .valid = true,
						 .answered = true,
						 .upload = ch->cur.upload,
						 .mode = ch->mode,
						 .index = ch->cur.index,
						 .sub = ch->cur.sub,
						 .cob_resp = ch->cob_resp,
						 .at_us = node_of(ch)->now_us };
	ch->done_pending = true;
	ch->done_abort = abort;
	return CS_IDLE;
}

/* A request that could not start: report it from the next tick (state
 * "start failed"), so that no completion ever runs inside the call that
 * submitted it. */
static int fail_start(struct cli_chan *ch, uint32_t abort)
{
	ch->start_abort = abort;
	return CS_START_FAILED;
}

static int abort_local(struct cli_chan *ch, uint32_t code)
{
	tx_mux(ch, SDO_CCS_ABORT << 5, code);
	ch->ended = (struct stale_xfer){ .valid = true,
					 .upload = ch->cur.upload,
					 .mode = ch->mode,
					 .index = ch->cur.index,
					 .sub = ch->cur.sub,
					 .cob_resp = ch->cob_resp,
					 .init_answered = ch->answered,
					 .at_us = node_of(ch)->now_us };
	return complete(ch, code);
}

/* A frame of the old transfer's data phase (segments, block acks and end,
 * block upload sub-block segments, which carry any byte 0)? */
static bool is_old_data_phase(const struct stale_xfer *s, const uint8_t *d)
{
	uint8_t cs = SDO_CS(d[0]);

	if (s->answered)
		return false; /* its data phase ended with the answer */
	switch (s->mode) {
	case SDO_MODE_SEGMENTED:
		return cs == (s->upload ? SDO_SCS_UP_SEG : SDO_SCS_DN_SEG);
	case SDO_MODE_BLOCK:
		return s->upload || d[0] == ((SDO_SCS_BLK_DN << 5) | SDO_BLK_ACK) ||
		       d[0] == ((SDO_SCS_BLK_DN << 5) | SDO_BLK_END);
	default:
		return false;
	}
}

/* A late frame of the transfer that ch->filter describes, arriving before
 * the first answer of the current one? Those are the old transfer's
 * segments (or block acks / sub-block segments), or its initiate answer or
 * abort naming the old object. An initiate answer or abort naming the
 * current object is the current answer; anything else is judged as an
 * answer to the current request. */
static bool is_initiate_or_abort(const uint8_t *d)
{
	uint8_t cs = SDO_CS(d[0]);
	return cs == SDO_SCS_UP_INIT || cs == SDO_SCS_DN_INIT || cs == SDO_SCS_BLK_DN ||
	       cs == SDO_SCS_BLK_UP || cs == SDO_SCS_ABORT;
}

static bool names_transfer(const struct stale_xfer *s, const uint8_t *d)
{
	return co_get_le16(&d[1]) == s->index && d[3] == s->sub;
}

static bool is_stale(const struct cli_chan *ch, const uint8_t *d)
{
	const struct stale_xfer *s = &ch->filter;
	bool names_cur = co_get_le16(&d[1]) == ch->cur.index && d[3] == ch->cur.sub;

	if (!s->valid)
		return false;
	if (is_initiate_or_abort(d) && names_cur)
		return false;
	if (is_initiate_or_abort(d) && names_transfer(s, d))
		return true;
	return is_old_data_phase(s, d);
}

/* Another initiate answer (or abort) naming the object of a transfer the
 * server already answered: a second device answers on that node-ID. Only
 * the default channels (580h + node-ID) name a node. */
static void second_answer(struct cli_chan *ch, const struct stale_xfer *s, const uint8_t *d,
			  uint64_t now_us)
{
	uint32_t cob = s->cob_resp;
	co_event ev = { .kind = CO_EV_SDO_CLIENT_SECOND_ANSWER, .now_us = now_us };

	/* (frames may carry a receive time a little before the answer's) */
	if (!s->valid || !s->answered || !is_initiate_or_abort(d) || !names_transfer(s, d) ||
	    (now_us > s->at_us && now_us - s->at_us > ch->timeout_us))
		return;
	if ((cob & SDO_COB_EXT) || cob <= SDO_COB_TX_BASE || cob > SDO_COB_TX_BASE + 127)
		return;
	ev.u.sdo_cli.channel = ch->num;
	ev.u.sdo_cli.upload = s->upload;
	ev.u.sdo_cli.node_id = (uint8_t)(cob - SDO_COB_TX_BASE);
	ev.u.sdo_cli.mode = s->mode;
	ev.u.sdo_cli.index = s->index;
	ev.u.sdo_cli.sub = s->sub;
	ev.u.sdo_cli.abort = SDO_CS(d[0]) == SDO_SCS_ABORT ? co_get_le32(&d[4]) : 0;
	co_node_emit(node_of(ch), &ev);
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
		int rc = ch->cur.sink(ch->cur.ctx, ch->offset, data, len, ch->total);

		if (rc < 0)
			return sdo_abort_of_errno(rc);
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

static int dn_send_segment(struct cli_chan *ch)
{
	uint32_t left = ch->total - ch->offset;
	uint32_t len = left < SDO_SEG_DATA ? left : SDO_SEG_DATA;
	bool last = left <= SDO_SEG_DATA;
	uint8_t d[8] = { 0 };

	if (src_read(ch, &d[1], len) < 0)
		return abort_local(ch, SDO_AB_STORE);
	d[0] = (uint8_t)((SDO_CCS_DN_SEG << 5) | ch->toggle | ((SDO_SEG_DATA - len) << 1) |
			 (last ? SDO_SEG_LAST : 0));
	tx(ch, d);
	return CS_DN_SEG;
}

static int start_download(struct cli_chan *ch)
{
	uint32_t size = ch->total;

	if (ch->mode == SDO_MODE_EXPEDITED) {
		uint8_t d[8] = { 0 };
		d[0] = (uint8_t)((SDO_CCS_DN_INIT << 5) | ((4u - size) << 2) | SDO_EXPEDITED |
				 SDO_SIZE_IND);
		co_put_le16(&d[1], ch->cur.index);
		d[3] = ch->cur.sub;
		if (src_read(ch, &d[4], size) < 0)
			return fail_start(ch, SDO_AB_STORE);
		tx(ch, d);
		return CS_DN_INIT;
	}
	if (ch->mode == SDO_MODE_BLOCK) {
		ch->sub_len = 0;
		tx_mux(ch, (SDO_CCS_BLK_DN << 5) | SDO_BLK_CRC | SDO_BLK_SIZE_IND, size);
		return CS_BLK_DN_INIT;
	}
	tx_mux(ch, (SDO_CCS_DN_INIT << 5) | SDO_SIZE_IND, size);
	return CS_DN_INIT;
}

static int dn_init_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct cli_chan *ch = obj;
	const uint8_t *d = f->data;

	(void)now_us;
	if (d[0] != (SDO_SCS_DN_INIT << 5))
		return abort_local(ch, SDO_AB_CMD);
	if (!mux_matches(ch, d))
		return abort_local(ch, SDO_AB_PARAM_INCOMPAT);
	if (ch->mode == SDO_MODE_EXPEDITED) {
		ch->offset = ch->total;
		return complete(ch, 0);
	}
	return dn_send_segment(ch);
}

static int dn_seg_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct cli_chan *ch = obj;
	const uint8_t *d = f->data;

	(void)now_us;
	if (SDO_CS(d[0]) != SDO_SCS_DN_SEG)
		return abort_local(ch, SDO_AB_CMD);
	if ((d[0] & SDO_TOGGLE) != ch->toggle)
		return abort_local(ch, SDO_AB_TOGGLE);
	ch->offset = ch->read_off;
	if (ch->offset >= ch->total)
		return complete(ch, 0);
	ch->toggle ^= SDO_TOGGLE;
	return dn_send_segment(ch);
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

/* Send one sub-block, then wait for its ack. */
static int blk_dn_send(struct cli_chan *ch)
{
	uint8_t segs;
	uint8_t d[8];

	if (!blk_fill(ch))
		return abort_local(ch, SDO_AB_STORE);
	segs = sdo_blk_tx_sub_block(&ch->btx, ch->sub_len, ch->read_off == ch->total);
	for (uint8_t seq = 1; seq <= segs; seq++) {
		sdo_blk_tx_segment(&ch->btx, seq, ch->sub_buf, d);
		tx(ch, d);
	}
	return CS_BLK_DN_ACK;
}

static int blk_dn_init_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct cli_chan *ch = obj;
	const uint8_t *d = f->data;

	(void)now_us;
	if ((d[0] & 0xE3u) != (SDO_SCS_BLK_DN << 5 | SDO_BLK_INIT))
		return abort_local(ch, SDO_AB_CMD);
	if (!mux_matches(ch, d))
		return abort_local(ch, SDO_AB_PARAM_INCOMPAT);
	if (!sdo_blk_size_valid(d[4]))
		return abort_local(ch, SDO_AB_BLK_SIZE);
	/* we asked for CRC; the server decides */
	sdo_blk_tx_start(&ch->btx, d[4], d[0] & SDO_BLK_CRC);
	return blk_dn_send(ch);
}

static int blk_dn_ack_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct cli_chan *ch = obj;
	uint32_t acked;
	bool done;
	uint32_t ab = sdo_blk_tx_ack(&ch->btx, f->data, ch->sub_buf, &acked, &done);

	(void)now_us;
	if (ab)
		return abort_local(ch, ab);
	if (done) {
		uint8_t e[8];
		ch->offset = ch->total;
		sdo_blk_tx_end(&ch->btx, e);
		tx(ch, e);
		return CS_BLK_DN_END;
	}
	/* Keep what was not acknowledged; it goes out again first. */
	memmove(ch->sub_buf, ch->sub_buf + acked, ch->sub_len - acked);
	ch->sub_len -= acked;
	ch->offset += acked;
	return blk_dn_send(ch);
}

static int blk_dn_end_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct cli_chan *ch = obj;

	(void)now_us;
	if (f->data[0] != ((SDO_SCS_BLK_DN << 5) | SDO_BLK_END))
		return abort_local(ch, SDO_AB_CMD);
	return complete(ch, 0);
}

/* ---- upload ------------------------------------------------------------- */

static int up_request_segment(struct cli_chan *ch)
{
	uint8_t d[8] = { (uint8_t)((SDO_CCS_UP_SEG << 5) | ch->toggle) };

	tx(ch, d);
	return CS_UP_SEG;
}

static int start_upload(struct cli_chan *ch)
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
		return CS_BLK_UP_INIT;
	}
	tx_mux(ch, SDO_CCS_UP_INIT << 5, 0);
	return CS_UP_INIT;
}

/* Initiate upload response (also the answer to a block upload initiate
 * when the server applies the protocol switch threshold). */
static int up_init_resp(struct cli_chan *ch, const uint8_t *d)
{
	uint32_t ab;

	if (d[0] & SDO_EXPEDITED) {
		uint32_t len = (d[0] & SDO_SIZE_IND) ? 4u - ((d[0] >> 2) & 3u) : 4u;
		ch->mode = SDO_MODE_EXPEDITED;
		ab = sink_put(ch, &d[4], len);
		return ab ? abort_local(ch, ab) : complete(ch, 0);
	}
	ch->mode = SDO_MODE_SEGMENTED;
	if (d[0] & SDO_SIZE_IND) {
		ch->total = co_get_le32(&d[4]);
		if (ch->cur.buf && ch->total > ch->cur.cap)
			return abort_local(ch, SDO_AB_NO_MEM);
	}
	ch->toggle = 0;
	return up_request_segment(ch);
}

static int up_init_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct cli_chan *ch = obj;
	const uint8_t *d = f->data;

	(void)now_us;
	if ((d[0] & 0xF0u) != (SDO_SCS_UP_INIT << 5))
		return abort_local(ch, SDO_AB_CMD);
	if (!mux_matches(ch, d))
		return abort_local(ch, SDO_AB_PARAM_INCOMPAT);
	return up_init_resp(ch, d);
}

static int up_seg_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct cli_chan *ch = obj;
	const uint8_t *d = f->data;
	uint32_t len = SDO_SEG_DATA - ((d[0] >> 1) & 7u);
	uint32_t ab;

	(void)now_us;
	if (SDO_CS(d[0]) != SDO_SCS_UP_SEG)
		return abort_local(ch, SDO_AB_CMD);
	if ((d[0] & SDO_TOGGLE) != ch->toggle)
		return abort_local(ch, SDO_AB_TOGGLE);
	ab = sink_put(ch, &d[1], len);
	if (!ab && (d[0] & SDO_SEG_LAST) && ch->total != UNKNOWN_SIZE && ch->offset != ch->total)
		ab = SDO_AB_TYPE_LEN;
	if (ab)
		return abort_local(ch, ab);
	if (d[0] & SDO_SEG_LAST)
		return complete(ch, 0);
	ch->toggle ^= SDO_TOGGLE;
	return up_request_segment(ch);
}

/* ---- block upload ------------------------------------------------------- */

static int blk_up_init_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct cli_chan *ch = obj;
	const uint8_t *d = f->data;
	uint8_t start[8] = { (SDO_CCS_BLK_UP << 5) | SDO_BLK_START };

	(void)now_us;
	if (SDO_CS(d[0]) == SDO_SCS_UP_INIT) /* protocol switch */
		return mux_matches(ch, d) ? up_init_resp(ch, d)
					  : abort_local(ch, SDO_AB_PARAM_INCOMPAT);
	if ((d[0] & 0xE1u) != (SDO_SCS_BLK_UP << 5))
		return abort_local(ch, SDO_AB_CMD);
	if (!mux_matches(ch, d))
		return abort_local(ch, SDO_AB_PARAM_INCOMPAT);
	if (d[0] & SDO_BLK_SIZE_IND) {
		ch->total = co_get_le32(&d[4]);
		if (ch->cur.buf && ch->total > ch->cur.cap)
			return abort_local(ch, SDO_AB_NO_MEM);
	}
	/* blksize: what start_upload() announced */
	sdo_blk_rx_start(&ch->brx, ch->brx.blksize, d[0] & SDO_BLK_CRC);
	ch->pend_valid = false;
	tx(ch, start);
	return CS_BLK_UP_SUB;
}

static int blk_up_ack(struct cli_chan *ch)
{
	uint8_t d[8];

	sdo_blk_rx_ack(&ch->brx, d);
	tx(ch, d);
	return ch->brx.last_seen ? CS_BLK_UP_END : CS_BLK_UP_SUB;
}

/* Sequence rules, duplicates and CRC: sdo_block.c, as for the server's
 * block download. Each segment is held back until the next one arrives:
 * the sink must only see data bytes, and the last segment's length is
 * only known at the end request. */
static int blk_up_sub_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct cli_chan *ch = obj;
	const uint8_t *d = f->data;
	unsigned act = sdo_blk_rx_segment(&ch->brx, d);

	(void)now_us;
	if (act & SDO_BLK_RX_BAD_SEQ)
		return abort_local(ch, SDO_AB_SEQ);
	if (act & SDO_BLK_RX_STORE) {
		if (ch->pend_valid) {
			uint32_t ab = sink_put(ch, ch->pend, SDO_SEG_DATA);
			if (ab)
				return abort_local(ch, ab);
		}
		memcpy(ch->pend, &d[1], SDO_SEG_DATA);
		ch->pend_valid = true;
	}
	if (act & SDO_BLK_RX_ACK)
		return blk_up_ack(ch);
	arm(ch);
	return CO_FSM_STAY;
}

static int blk_up_end_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct cli_chan *ch = obj;
	const uint8_t *d = f->data;
	uint8_t resp[8] = { (SDO_CCS_BLK_UP << 5) | SDO_BLK_END };
	uint32_t last_len;
	uint32_t ab = 0;

	(void)now_us;
	if (sdo_blk_rx_is_dup(&ch->brx, d)) {
		arm(ch);
		return CO_FSM_STAY;
	}
	if (!sdo_blk_rx_end(d, &last_len))
		return abort_local(ch, SDO_AB_CMD);
	if (ch->pend_valid)
		ab = sink_put(ch, ch->pend, last_len);
	if (!ab && ch->total != UNKNOWN_SIZE && ch->offset != ch->total)
		ab = SDO_AB_TYPE_LEN;
	if (!ab && !sdo_blk_rx_crc_ok(&ch->brx, d, last_len))
		ab = SDO_AB_CRC;
	if (ab)
		return abort_local(ch, ab);
	tx(ch, resp);
	return complete(ch, 0);
}

/* ---- idle, start failed, leased ------------------------------------------------ */

/* Idle: no timer, no receiver. Confirm the request that just ended (its
 * con, then the event), then start what waits; a con may already submit
 * the next request to this channel, which then starts from here. */
static int idle_on_enter(void *obj, uint64_t now_us)
{
	struct cli_chan *ch = obj;
	sdo_client_req r = ch->cur;

	(void)now_us;
	ch->deadline = CO_NO_DEADLINE;
	if (!ch->done_pending)
		return CO_FSM_STAY;
	ch->done_pending = false;
	/* an answered transfer keeps listening: a second answer to it means
	 * a second device on that node-ID (second_answer()); so does one we
	 * aborted before its initiate was answered: each late frame of it
	 * restarts the server's settle time (cli_rx) */
	if (ch->done_abort && ch->answered)
		co_rx_disable(node_of(ch), ch->rx_handle);
	confirm(node_of(ch), &r, ch->num, ch->mode, ch->done_abort, ch->offset, ch->answered);
	kick_all(ch->cli);
	return CO_FSM_STAY;
}

/* Every transfer state: the per-frame timeout runs from here. */
static int transfer_on_enter(void *obj, uint64_t now_us)
{
	(void)now_us;
	arm(obj);
	return CO_FSM_STAY;
}

static int transfer_on_timeout(void *obj, uint64_t now_us)
{
	(void)now_us;
	return abort_local(obj, SDO_AB_TIMEOUT);
}

static int start_failed_on_enter(void *obj, uint64_t now_us)
{
	struct cli_chan *ch = obj;

	(void)now_us;
	ch->deadline = node_of(ch)->now_us;
	co_node_deadline_lower(node_of(ch), ch->deadline);
	return CO_FSM_STAY;
}

static int start_failed_on_timeout(void *obj, uint64_t now_us)
{
	struct cli_chan *ch = obj;

	(void)now_us;
	return complete(ch, ch->start_abort);
}

static int leased_on_enter(void *obj, uint64_t now_us)
{
	struct cli_chan *ch = obj;

	(void)now_us;
	ch->deadline = CO_NO_DEADLINE; /* the relay keeps its own timers */
	return CO_FSM_STAY;
}

/* ---- the machine ----------------------------------------------------------------- */

#define TRANSFER_STATE(nm, frame_fn)                                             \
	{                                                                        \
		.name = nm, .on_enter = transfer_on_enter, .on_frame = frame_fn, \
		.on_timeout = transfer_on_timeout                                \
	}

/* Frames of a leased channel and of the idle / start failed states never
 * reach the table (cli_rx). */
static const co_fsm_state cli_states[CS_COUNT] = {
	[CS_IDLE] = { .name = "idle", .on_enter = idle_on_enter },
	[CS_DN_INIT] = TRANSFER_STATE("download initiate", dn_init_on_frame),
	[CS_DN_SEG] = TRANSFER_STATE("download segment", dn_seg_on_frame),
	[CS_UP_INIT] = TRANSFER_STATE("upload initiate", up_init_on_frame),
	[CS_UP_SEG] = TRANSFER_STATE("upload segment", up_seg_on_frame),
	[CS_BLK_DN_INIT] = TRANSFER_STATE("block download initiate", blk_dn_init_on_frame),
	[CS_BLK_DN_ACK] = TRANSFER_STATE("block download ack", blk_dn_ack_on_frame),
	[CS_BLK_DN_END] = TRANSFER_STATE("block download end", blk_dn_end_on_frame),
	[CS_BLK_UP_INIT] = TRANSFER_STATE("block upload initiate", blk_up_init_on_frame),
	[CS_BLK_UP_SUB] = TRANSFER_STATE("block upload sub-block", blk_up_sub_on_frame),
	[CS_BLK_UP_END] = TRANSFER_STATE("block upload end", blk_up_end_on_frame),
	[CS_START_FAILED] = { .name = "start failed",
			      .on_enter = start_failed_on_enter,
			      .on_timeout = start_failed_on_timeout },
	[CS_LEASED] = { .name = "leased", .on_enter = leased_on_enter },
};

static const co_fsm_def cli_def = {
	.name = "sdo_client",
	.states = cli_states,
	.n_states = CS_COUNT,
};

const char *sdo_client_state_to_string(const co_node *node, uint8_t channel)
{
	const struct sdo_client *cli = node->sdo_cli;

	if (!cli || channel >= cli->n)
		return "?";
	return co_fsm_state_name(&cli_def, state_of(&cli->ch[channel]));
}

/* ---- receive, start, queue ------------------------------------------------ */

static int restart_without_block(struct cli_chan *ch)
{
	ch->fell_back = true;
	ch->offset = ch->read_off = 0;
	ch->mode = ch->cur.upload                                  ? SDO_MODE_SEGMENTED
		   : (ch->total >= 1 && ch->total <= SDO_EXP_DATA) ? SDO_MODE_EXPEDITED
								   : SDO_MODE_SEGMENTED;
	return ch->cur.upload ? start_upload(ch) : start_download(ch);
}

/* A server abort while a transfer runs: maybe fall back from block. */
static int server_abort(struct cli_chan *ch, int st, const uint8_t *d)
{
	uint32_t code = co_get_le32(&d[4]);
	bool refused = code == SDO_AB_CMD || code == SDO_AB_UNSUPP_ACCESS;

	if (refused && !ch->fell_back && (st == CS_BLK_DN_INIT || st == CS_BLK_UP_INIT))
		return restart_without_block(ch);
	return complete(ch, code);
}

static void cli_rx(co_node *node, void *arg, const co_frame *f, uint64_t now_us)
{
	struct cli_chan *ch = arg;
	const uint8_t *d = f->data;
	int st = state_of(ch);

	(void)node;
	if (f->len != 8 || (f->flags & CO_FRAME_RTR))
		return;
	if (st == CS_IDLE) {
		/* no transfer to this server started since (that would have
		 * taken `ended` as its filter) */
		if (ch->ended.valid && !ch->ended.answered)
			ch->ended.at_us = now_us; /* not quiet yet: settle again */
		second_answer(ch, &ch->ended, d, now_us);
		return;
	}
	if (st == CS_START_FAILED)
		return;
	if (st == CS_LEASED) {
		ch->lease_fn(ch->lease_arg, d, now_us);
		return;
	}
	if (is_stale(ch, d)) {
		second_answer(ch, &ch->filter, d, now_us);
		return;
	}
	ch->filter.valid = false; /* the server answers the current request */
	ch->answered = true;
	if (st == CS_BLK_UP_SUB ? sdo_blk_seg_is_abort(d)
				: is_abort(d) && !sdo_blk_rx_is_dup(&ch->brx, d)) {
		co_fsm_goto(&ch->fsm, server_abort(ch, st, d), now_us);
		return;
	}
	co_fsm_frame(&ch->fsm, f, now_us);
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
	case SDO_MODE_BLOCK:
		return SDO_MODE_BLOCK;
	case SDO_MODE_SEGMENTED:
		return SDO_MODE_SEGMENTED;
	case SDO_MODE_EXPEDITED:
		return r->size >= 1 && r->size <= 4 ? SDO_MODE_EXPEDITED : SDO_MODE_SEGMENTED;
	default:
		if (r->size >= 1 && r->size <= 4)
			return SDO_MODE_EXPEDITED;
		return r->size >= thr ? SDO_MODE_BLOCK : SDO_MODE_SEGMENTED;
	}
}

/* A relayed request's server, as an identity no COB-ID of this bus has
 * (bits 31 and 30 set: a 1280h value with "not valid" and "dynamic"). */
#define RELAY_ID 0xC0000000u

static uint32_t req_cob_req(const sdo_client_req *r)
{
	if (r->relay)
		return RELAY_ID | r->relay_target;
	return r->cob_req ? r->cob_req : SDO_COB_RX_BASE + r->node_id;
}

static uint32_t req_cob_resp(const sdo_client_req *r)
{
	if (r->relay)
		return RELAY_ID | r->relay_target;
	return r->cob_resp ? r->cob_resp : SDO_COB_TX_BASE + r->node_id;
}

/* Another channel is talking to the same server right now? */
static bool target_busy(const struct sdo_client *cli, const struct cli_chan *self, uint32_t resp)
{
	for (uint8_t i = 0; i < cli->n; i++) {
		const struct cli_chan *o = &cli->ch[i];
		if (o != self && state_of(o) != CS_IDLE && o->cob_resp == resp)
			return true;
	}
	return false;
}

/* A transfer of ours with this server ended by our own abort before the
 * server answered its last request, and the server has not been quiet for
 * SETTLE_US since (each frame of it restarts the time, cli_rx): it may
 * still send that answer and the rest of the transfer. A relay would hand
 * them on as answers (it cannot tell them from the next requester's), and
 * so would a transfer of ours naming the same object if what is still
 * due is the initiate's answer (is_stale() tells only another object's
 * apart, or the old data phase's frames): both wait. */
#define SETTLE_US 100000u

static bool unsettled(const struct stale_xfer *e, uint32_t resp, uint64_t now_us)
{
	return e->valid && !e->answered && e->cob_resp == resp && now_us - e->at_us < SETTLE_US;
}

static bool settling(const struct sdo_client *cli, uint32_t resp, uint64_t now_us)
{
	for (uint8_t i = 0; i < cli->n; i++)
		if (unsettled(&cli->ch[i].ended, resp, now_us))
			return true;
	return false;
}

/* ---- the gate (sdo_client_set_gate) --------------------------------------- */

/* A refusal of the gate: whatever waits is tried again from the tick. */
#define GATE_RETRY_US 100000u

/* Whatever waits is tried again from the tick at `at` (or earlier). */
static void retry_at(struct sdo_client *cli, uint64_t at)
{
	if (at < cli->retry_us) {
		cli->retry_us = at;
		co_node_deadline_lower(cli->node, at);
	}
}

static void gate_refused(struct sdo_client *cli)
{
	if (cli->retry_us == CO_NO_DEADLINE)
		retry_at(cli, cli->node->now_us + GATE_RETRY_US);
}

/* The node-ID of a server on this bus the gate knows (580h + n), else 0. */
static uint8_t gate_server_of(uint32_t resp)
{
	return resp > SDO_COB_TX_BASE && resp <= SDO_COB_TX_BASE + 127u
		       ? (uint8_t)(resp - SDO_COB_TX_BASE)
		       : 0;
}

static bool srv_is_held(const struct sdo_client *cli, uint8_t n)
{
	return cli->srv_held[n / 64u] >> (n % 64u) & 1u;
}

/* May a request of the node's own start a transfer with this server? */
static bool gate_take_server(struct sdo_client *cli, uint32_t resp)
{
	uint8_t n = gate_server_of(resp);

	if (!cli->gate || !n || srv_is_held(cli, n))
		return true;
	if (!cli->gate(cli->gate_ctx, SDO_CLIENT_GATE_TAKE_SERVER, n)) {
		gate_refused(cli);
		return false;
	}
	cli->srv_held[n / 64u] |= 1ull << (n % 64u);
	return true;
}

/* May a request of the node's own use this (idle) channel? */
static bool gate_take_channel(struct cli_chan *ch)
{
	struct sdo_client *cli = ch->cli;

	if (!cli->gate || ch->gated_out)
		return true;
	if (!cli->gate(cli->gate_ctx, SDO_CLIENT_GATE_TAKE_CHANNEL, ch->num)) {
		gate_refused(cli);
		return false;
	}
	ch->gated_out = true;
	return true;
}

/* Something else talks to the server, or the gate lent it elsewhere? */
static bool server_blocked(struct sdo_client *cli, const struct cli_chan *self, uint32_t resp)
{
	return target_busy(cli, self, resp) || !gate_take_server(cli, resp);
}

static uint64_t gate_next(const struct sdo_client *cli);

/* Give the gate back what the node's own requests no longer use. */
static void gate_sync(struct sdo_client *cli)
{
	if (!cli->gate)
		return;
	for (uint8_t i = 0; i < cli->n; i++) {
		struct cli_chan *ch = &cli->ch[i];
		if (ch->gated_out && state_of(ch) == CS_IDLE && ch->q_len == 0) {
			ch->gated_out = false;
			cli->gate(cli->gate_ctx, SDO_CLIENT_GATE_FREE_CHANNEL, ch->num);
		}
	}
	for (uint8_t n = 1; n <= 127; n++) {
		uint32_t resp = SDO_COB_TX_BASE + n;
		if (!srv_is_held(cli, n) || target_busy(cli, NULL, resp) ||
		    settling(cli, resp, cli->node->now_us))
			continue;
		cli->srv_held[n / 64u] &= ~(1ull << (n % 64u));
		cli->gate(cli->gate_ctx, SDO_CLIENT_GATE_FREE_SERVER, n);
	}
	/* a server still settling goes back from the tick at its end, also
	 * when nothing else would tick the node (a transfer cancelled from
	 * outside) */
	co_node_deadline_lower(cli->node, gate_next(cli));
}

/* May r start now? Not while a late answer about the same object may
 * still come, nor while another channel talks to its server or the gate
 * lent the server elsewhere. */
static bool may_start(struct sdo_client *cli, const struct cli_chan *self, const sdo_client_req *r)
{
	uint32_t resp = req_cob_resp(r);
	uint64_t now_us = cli->node->now_us;

	for (uint8_t i = 0; i < cli->n; i++) {
		const struct stale_xfer *e = &cli->ch[i].ended;
		if (unsettled(e, resp, now_us) && !e->init_answered && e->index == r->index &&
		    e->sub == r->sub) {
			retry_at(cli, e->at_us + SETTLE_US);
			return false;
		}
	}
	return !server_blocked(cli, self, resp);
}

/* Late frames of a transfer to this server that some channel ended with
 * an abort frame are to be ignored (is_stale()). */
static void take_filter(struct cli_chan *ch)
{
	ch->filter.valid = false;
	for (uint8_t i = 0; i < ch->cli->n; i++) {
		struct stale_xfer *st = &ch->cli->ch[i].ended;
		if (st->valid && st->cob_resp == ch->cob_resp) {
			ch->filter = *st;
			st->valid = false;
		}
	}
}

/* 1280h+n shows the current target on this bus, as a manager would set
 * it (a relayed request's target is elsewhere). */
static void show_target(struct cli_chan *ch, const sdo_client_req *r)
{
	if (r->relay)
		return;
	if (ch->od_cob[0])
		co_od_entry_set_raw(ch->od_cob[0], ch->cob_req);
	if (ch->od_cob[1])
		co_od_entry_set_raw(ch->od_cob[1], ch->cob_resp);
	if (ch->od_node)
		co_od_entry_set_raw(ch->od_node, r->node_id);
}

/* Where the answers come from: the server's COB-ID on the bus, or the
 * relay (no receiver on the bus then). 0 or -errno. */
static int listen_for_answers(struct cli_chan *ch)
{
	co_node *node = node_of(ch);

	if (ch->cur.relay) {
		co_rx_disable(node, ch->rx_handle);
		return 0;
	}
	return co_rx_move(node, ch->rx_handle, ch->cob_resp & CO_FRAME_EFF_MASK,
			  (ch->cob_resp & SDO_COB_EXT) ? CO_FRAME_EXT : 0);
}

/* Set the channel up for r and send its first frame; the state that
 * waits for the answer (or "start failed"). */
static int start_state(struct cli_chan *ch, const sdo_client_req *r)
{
	co_node *node = node_of(ch);

	ch->cur = *r;
	ch->cob_req = req_cob_req(r);
	ch->cob_resp = req_cob_resp(r);
	take_filter(ch);
	ch->timeout_us =
		(uint64_t)(r->timeout_ms ? r->timeout_ms : node->cfg.sdo_client_timeout_ms) * 1000u;
	ch->mode = pick_mode(ch, r);
	ch->fell_back = false;
	sdo_blk_rx_reset(&ch->brx);
	ch->offset = ch->read_off = 0;
	ch->toggle = 0;
	ch->total = r->upload ? UNKNOWN_SIZE : r->size;
	ch->answered = false;
	show_target(ch, r);
	/* CiA 301 §7.3.2.2: no SDO in STOPPED; reported from the next tick
	 * like any request that cannot start. */
	if (co_nmt_get_state(node) == CO_NMT_STOPPED)
		return fail_start(ch, SDO_AB_DEV_STATE);
	if (listen_for_answers(ch) != 0)
		return fail_start(ch, SDO_AB_NO_RESOURCE);
	return r->upload ? start_upload(ch) : start_download(ch);
}

static void start(struct cli_chan *ch, const sdo_client_req *r)
{
	co_fsm_goto(&ch->fsm, start_state(ch, r), node_of(ch)->now_us);
}

/* Start the head of the queue if the channel is idle and the target free. */
static void kick(struct cli_chan *ch)
{
	const sdo_client_req *r;

	if (state_of(ch) != CS_IDLE || ch->q_len == 0)
		return;
	r = &ch->q[ch->q_head];
	if (!may_start(ch->cli, ch, r) || !gate_take_channel(ch))
		return;
	sdo_client_req tmp = *r;
	ch->q_head = (uint16_t)((ch->q_head + 1) % node_of(ch)->cfg.sdo_client_queue_len);
	ch->q_len--;
	start(ch, &tmp);
}

/* Free for the pool: idle, nothing waiting in its own FIFO, and not lent
 * out by the gate. */
static struct cli_chan *free_channel(struct sdo_client *cli)
{
	for (uint8_t i = 0; i < cli->n; i++)
		if (state_of(&cli->ch[i]) == CS_IDLE && cli->ch[i].q_len == 0 &&
		    gate_take_channel(&cli->ch[i]))
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
		cli->pool_head = (uint16_t)((cli->pool_head + 1) %
					    cli->node->cfg.sdo_client_pool_len);
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

		if (!may_start(cli, NULL, r)) {
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
	gate_sync(cli);
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
	gate_sync(cli);
	return 0;
}

int sdo_client_read(co_node *node, uint8_t channel, uint8_t node_id, uint16_t index, uint8_t sub,
		    uint8_t *buf, uint32_t cap, uint32_t timeout_ms, uint64_t tag, uint64_t now_us)
{
	sdo_client_req r = { .upload = true,
			     .node_id = node_id,
			     .index = index,
			     .sub = sub,
			     .timeout_ms = timeout_ms,
			     .tag = tag,
			     .buf = buf,
			     .cap = cap };
	return sdo_client_submit(node, channel, &r, now_us);
}

int sdo_client_write(co_node *node, uint8_t channel, uint8_t node_id, uint16_t index, uint8_t sub,
		     const uint8_t *data, uint32_t size, uint32_t timeout_ms, uint64_t tag,
		     uint64_t now_us)
{
	sdo_client_req r = { .upload = false,
			     .node_id = node_id,
			     .index = index,
			     .sub = sub,
			     .timeout_ms = timeout_ms,
			     .tag = tag,
			     .data = data,
			     .size = size };
	return sdo_client_submit(node, channel, &r, now_us);
}

/* Running on ch with this tag: abort it (an abort frame unless it never
 * got on the wire). */
static bool cancel_running(struct cli_chan *ch, uint64_t tag, uint32_t abort)
{
	int st = state_of(ch);

	if (st == CS_IDLE || st == CS_LEASED || ch->cur.tag != tag)
		return false;
	co_fsm_goto(&ch->fsm, st == CS_START_FAILED ? complete(ch, abort) : abort_local(ch, abort),
		    node_of(ch)->now_us);
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
		confirm(node_of(ch), &r, ch->num, r.mode, abort, 0, false);
		gate_sync(ch->cli); /* its channel may be free now */
		return true;
	}
	return false;
}

int sdo_client_cancel(co_node *node, uint8_t channel, uint64_t tag, uint32_t abort, uint64_t now_us)
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
		confirm(node, &r, SDO_CLIENT_NO_CHANNEL, r.mode, abort, 0, false);
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
		struct cli_chan *ch = NULL;
		if (may_start(cli, NULL, req))
			ch = free_channel(cli);
		if (ch)
			start(ch, req);
		gate_sync(cli);
		return ch ? 0 : -EBUSY;
	}
	if (cli->pool_len >= node->cfg.sdo_client_pool_len)
		return -ENOSPC;
	*pool_at(cli, cli->pool_len) = *req;
	cli->pool_len++;
	pool_kick(cli);
	gate_sync(cli);
	return 0;
}

int sdo_client_relay_recv(co_node *node, uint64_t tag, const uint8_t d[8], uint64_t now_us)
{
	struct sdo_client *cli = node->sdo_cli;
	co_frame f;

	for (uint8_t i = 0; cli && i < cli->n; i++) {
		struct cli_chan *ch = &cli->ch[i];
		int st = state_of(ch);
		if (st == CS_IDLE || st == CS_LEASED || st == CS_START_FAILED || !ch->cur.relay ||
		    ch->cur.tag != tag)
			continue;
		node->now_us = now_us;
		co_frame_init(&f, ch->cob_resp & CO_FRAME_EFF_MASK, 8);
		memcpy(f.data, d, 8);
		cli_rx(node, ch, &f, now_us);
		return 0;
	}
	return -ENOENT;
}

/* ---- relay lease (CiA 302-7) ------------------------------------------------ */

/* When the gate wants the tick again: a refused request's retry, or the
 * end of a held server's settling time. */
static uint64_t gate_next(const struct sdo_client *cli)
{
	uint64_t next = cli->retry_us;

	for (uint8_t i = 0; i < cli->n; i++) {
		const struct stale_xfer *e = &cli->ch[i].ended;
		uint8_t n = gate_server_of(e->cob_resp);
		if (e->valid && !e->answered && n && srv_is_held(cli, n) &&
		    e->at_us + SETTLE_US > cli->node->now_us && e->at_us + SETTLE_US < next)
			next = e->at_us + SETTLE_US;
	}
	return next;
}

/* Lend ch raw toward r's server (the checks done). */
static int lease_bind(struct cli_chan *ch, const sdo_client_req *r, sdo_client_raw_fn fn, void *arg,
		      uint64_t now_us)
{
	co_node *node = node_of(ch);
	struct sdo_client *cli = ch->cli;
	uint32_t resp = req_cob_resp(r);

	if (co_rx_move(node, ch->rx_handle, resp & CO_FRAME_EFF_MASK,
		       (resp & SDO_COB_EXT) ? CO_FRAME_EXT : 0) != 0)
		return -ENOSPC;
	/* the relay's frames to and from that server are not answers of ours */
	for (uint8_t i = 0; i < cli->n; i++)
		if (cli->ch[i].ended.cob_resp == resp)
			cli->ch[i].ended.valid = false;
	ch->cur = *r;
	ch->cob_req = req_cob_req(r);
	ch->cob_resp = resp;
	ch->lease_fn = fn;
	ch->lease_arg = arg;
	co_fsm_goto(&ch->fsm, CS_LEASED, now_us);
	if (ch->od_cob[0])
		co_od_entry_set_raw(ch->od_cob[0], ch->cob_req);
	if (ch->od_cob[1])
		co_od_entry_set_raw(ch->od_cob[1], ch->cob_resp);
	if (ch->od_node)
		co_od_entry_set_raw(ch->od_node, r->node_id);
	return ch->num;
}

int sdo_client_lease(co_node *node, uint8_t node_id, uint32_t cob_req, uint32_t cob_resp,
		     sdo_client_raw_fn fn, void *arg, uint64_t now_us)
{
	struct sdo_client *cli = node->sdo_cli;
	sdo_client_req r = { .node_id = node_id, .cob_req = cob_req, .cob_resp = cob_resp };
	struct cli_chan *ch;
	int rc;

	if (!cli || !fn || node_id < 1 || node_id > 127)
		return -EINVAL;
	node->now_us = now_us;
	if (settling(cli, req_cob_resp(&r), now_us) || server_blocked(cli, NULL, req_cob_resp(&r)))
		rc = -EALREADY;
	else if (!(ch = free_channel(cli)))
		rc = -EBUSY;
	else
		rc = lease_bind(ch, &r, fn, arg, now_us);
	gate_sync(cli);
	return rc;
}

int sdo_client_lease_channel(co_node *node, uint8_t channel, uint8_t node_id, sdo_client_raw_fn fn,
			     void *arg, uint64_t now_us)
{
	struct sdo_client *cli = node->sdo_cli;
	sdo_client_req r = { .node_id = node_id };
	struct cli_chan *ch;
	int rc;

	if (!cli || !fn || node_id < 1 || node_id > 127 || channel >= cli->n)
		return -EINVAL;
	node->now_us = now_us;
	ch = &cli->ch[channel];
	if (state_of(ch) != CS_IDLE || ch->gated_out)
		return -EBUSY;
	if (target_busy(cli, NULL, req_cob_resp(&r)) || settling(cli, req_cob_resp(&r), now_us))
		return -EALREADY;
	rc = lease_bind(ch, &r, fn, arg, now_us);
	if (rc >= 0)
		ch->gated_out = true; /* given back at its end (gate_sync) */
	return rc;
}

static struct cli_chan *leased(co_node *node, uint8_t channel)
{
	struct sdo_client *cli = node->sdo_cli;

	if (!cli || channel >= cli->n || state_of(&cli->ch[channel]) != CS_LEASED)
		return NULL;
	return &cli->ch[channel];
}

int sdo_client_lease_move(co_node *node, uint8_t channel, uint8_t node_id, uint64_t now_us)
{
	struct cli_chan *ch = leased(node, channel);
	sdo_client_req r = { .node_id = node_id };
	int rc;

	if (!ch)
		return -ENOENT;
	if (node_id < 1 || node_id > 127)
		return -EINVAL;
	node->now_us = now_us;
	if (target_busy(ch->cli, ch, req_cob_resp(&r)) ||
	    settling(ch->cli, req_cob_resp(&r), now_us))
		return -EALREADY;
	rc = lease_bind(ch, &r, ch->lease_fn, ch->lease_arg, now_us);
	if (rc < 0)
		return rc;
	kick_all(ch->cli);
	return 0;
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
	co_fsm_goto(&ch->fsm, CS_IDLE, now_us); /* nothing to confirm */
	ch->lease_fn = NULL;
	co_rx_disable(node, ch->rx_handle);
	kick_all(ch->cli);
	return 0;
}

void sdo_client_set_gate(co_node *node, sdo_client_gate_fn fn, void *ctx)
{
	struct sdo_client *cli = node->sdo_cli;

	if (!cli)
		return;
	cli->gate = fn;
	cli->gate_ctx = ctx;
	cli->srv_held[0] = cli->srv_held[1] = 0;
	cli->retry_us = CO_NO_DEADLINE;
	for (uint8_t i = 0; i < cli->n; i++) {
		struct cli_chan *ch = &cli->ch[i];
		uint8_t n = gate_server_of(ch->cob_resp);
		ch->gated_out = fn != NULL; /* what is free is announced by gate_sync */
		if (fn && n && state_of(ch) != CS_IDLE && fn(ctx, SDO_CLIENT_GATE_TAKE_SERVER, n))
			cli->srv_held[n / 64u] |= 1ull << (n % 64u);
	}
	gate_sync(cli);
}

void sdo_client_gate_kick(co_node *node, uint64_t now_us)
{
	struct sdo_client *cli = node->sdo_cli;

	/* nothing refused waits for a retry: the lease's end kicked the rest */
	if (!cli || !cli->gate || cli->retry_us == CO_NO_DEADLINE)
		return;
	node->now_us = now_us;
	cli->retry_us = CO_NO_DEADLINE;
	kick_all(cli);
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
	return cli->ch[channel].q_len + (state_of(&cli->ch[channel]) != CS_IDLE);
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
	cli->retry_us = CO_NO_DEADLINE;
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
		co_fsm_init(&ch->fsm, &cli_def, ch, CS_IDLE);
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
		if (state_of(ch) != CS_IDLE && now_us >= ch->deadline)
			co_fsm_timeout(&ch->fsm, now_us);
	}
	if (now_us >= cli->retry_us) {
		cli->retry_us = CO_NO_DEADLINE;
		kick_all(cli); /* what the gate or a settling server held back; a refusal re-arms */
	}
	gate_sync(cli); /* servers whose settling time ended */
	next = gate_next(cli);
	/* A second pass: completions above may have started queued requests. */
	for (uint8_t i = 0; i < cli->n; i++)
		if (state_of(&cli->ch[i]) != CS_IDLE && cli->ch[i].deadline < next)
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
		if (state_of(ch) == CS_IDLE)
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

	if (!cli || state != CO_NMT_STOPPED)
		return;
	for (uint8_t i = 0; i < cli->n; i++) {
		struct cli_chan *ch = &cli->ch[i];
		int st = state_of(ch);
		if (st != CS_IDLE && st != CS_START_FAILED &&
		    st != CS_LEASED) /* a relay lease: its owner's business */
			co_fsm_goto(&ch->fsm, complete(ch, SDO_AB_DEV_STATE), now_us);
	}
}

const co_service co_svc_sdo_client = {
	.name = "sdo-client",
	.init = cli_init,
	.fini = cli_fini,
	.tick = cli_tick,
	.reset_comm = cli_reset_comm,
	.nmt_changed = cli_nmt_changed,
};
