/* SPDX-License-Identifier: MIT */
/*
 * SDO server (CiA 301 §7.2.4). One core/fsm.h machine per channel: the
 * table srv_states[] gives each state its frame handler, which returns the
 * next state. Every transfer state shares one on_enter and one timeout
 * rule (the per-frame timeout, restarted on every frame the channel
 * receives or sends, aborts with 0x05040000). A transfer ends through
 * finish(), which returns idle; idle's on_enter emits the one
 * CO_EV_SDO_SERVER_DONE. A deferred hook answers through on_con
 * (sdo_server_continue). The sub-block rules of both block directions
 * (sequence, duplicates, ack, CRC) are shared with the client in
 * sdo_block.c.
 *
 * Frame layout reminders (byte 0):
 *   initiate download   001 x nn e s  -> 011 00000 (0x60)
 *   download segment    000 t nnn c   -> 001 t 0000
 *   initiate upload     010 00000     -> 010 x nn e s
 *   upload segment      011 t 0000    -> 000 t nnn c
 *   block download      110 xx cc s 0 -> 101 xx sc 00, blksize in byte 4
 *     sub-block segment c seqno(7)     -> 101 xxx 10 ackseq blksize (ack)
 *     end                110 nnn x 1   -> 101 xxx 01
 *   block upload        101 xx cc 00 (blksize, pst) -> 110 xx sc s 0 (size)
 *     start             101 xxx 11     -> segments c seqno(7)
 *     ack               101 xxx 10 ackseq blksize
 *     end (server)      110 nnn x 1 crc -> 101 xxx 01
 *   abort               100 00000, abort code in bytes 4..7
 */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "core/co_internal.h"
#include "core/fsm.h"
#include "core/nmt.h"
#include "core/sdo_block.h"
#include "core/sdo_server.h"

enum srv_state {
	SS_IDLE,
	SS_DN_SEG,       /* segmented download: expecting a segment */
	SS_UP_SEG,       /* segmented upload: expecting a segment request */
	SS_BLK_DN_SUB,   /* block download: receiving sub-block segments */
	SS_BLK_DN_END,   /* block download: expecting the end request */
	SS_BLK_UP_START, /* block upload: expecting "start upload" */
	SS_BLK_UP_ACK,   /* block upload: sub-block sent, expecting an ack */
	SS_BLK_UP_END,   /* block upload: end sent, expecting its response */
	SS_DEFERRED,     /* a hook answers later (sdo_server_continue) */
	SS_ROUTED,       /* CiA 302-7: frames go to the routing hook */
	SS_COUNT
};

enum defer_kind {
	DEFER_COMMIT,  /* store the staged value, send `pending`, finish */
	DEFER_PROCEED, /* send `pending`, enter resume_state */
	DEFER_READ,    /* start the upload (normal or block) */
};

struct srv_chan {
	struct sdo_server *srv;
	uint8_t num;
	co_fsm fsm;          /* state: enum srv_state (srv_states[]) */
	bool done_pending;   /* the transfer ended: idle's on_enter reports */
	uint32_t done_abort; /* ... with this abort code (0 = success) */
	co_frame route_ind;  /* the network indication handed to routing */
	int rx_handle;
	uint32_t cob_rx; /* 1200h+n sub 1 (client -> server), incl. bit 31 */
	uint32_t cob_tx; /* sub 2 (server -> client) */
	uint64_t deadline;

	/* current transfer */
	co_od_entry *e;
	uint16_t index;
	uint8_t sub;
	uint8_t mode; /* sdo_mode */
	bool upload;
	uint8_t toggle;
	bool size_ind;
	uint32_t size;   /* indicated (download) or total (upload) size */
	uint32_t offset; /* bytes done */

	uint8_t *dst; /* download: stage or e->data (in place) */
	uint32_t dst_cap;
	bool in_place;
	const uint8_t *src; /* upload: e->data or the deferred data */

	/* block */
	struct sdo_blk_rx brx; /* download: sequence, duplicates, CRC */
	uint32_t last_off;     /* download: offset of the last segment */
	struct sdo_blk_tx btx; /* upload: sub-block, CRC */
	uint8_t pst;           /* upload: protocol switch threshold from the client */
	uint32_t blk_start;    /* upload: offset of the current sub-block */

	/* deferred answer */
	uint8_t defer;
	uint8_t resume_state;
	bool defer_block;
	bool reapply; /* own COB-ID written over this channel: apply at end */
	uint32_t stage_len;
	co_frame pending;

	uint8_t *stage; /* cfg.sdo_stage_size bytes, allocated at init */
};

struct sdo_server {
	co_node *node;
	const sdo_server_route_ops *route; /* NULL: no routing (cs 7 refused) */
	void *route_ctx;
	uint8_t n;
	struct srv_chan ch[];
};

/* ---- helpers ------------------------------------------------------------ */

static co_node *node_of(const struct srv_chan *ch)
{
	return ch->srv->node;
}

static const co_node_config *cfg_of(const struct srv_chan *ch)
{
	return &node_of(ch)->cfg;
}

static int state_of(const struct srv_chan *ch)
{
	return co_fsm_state_of(&ch->fsm);
}

static void arm(struct srv_chan *ch)
{
	co_node *node = node_of(ch);

	ch->deadline = node->now_us + (uint64_t)node->cfg.sdo_server_timeout_ms * 1000u;
	co_node_deadline_lower(node, ch->deadline);
}

static void frame_init(const struct srv_chan *ch, co_frame *f, uint8_t cmd)
{
	co_frame_init(f, ch->cob_tx & CO_FRAME_EFF_MASK, 8);
	if (ch->cob_tx & SDO_COB_EXT)
		f->flags |= CO_FRAME_EXT;
	f->data[0] = cmd;
}

/* A frame that carries index/sub in bytes 1..3 (initiate, end, abort). */
static void send_mux(struct srv_chan *ch, uint8_t cmd, const uint8_t *payload4)
{
	co_frame f;

	frame_init(ch, &f, cmd);
	co_put_le16(&f.data[1], ch->index);
	f.data[3] = ch->sub;
	if (payload4)
		memcpy(&f.data[4], payload4, 4);
	co_node_send(node_of(ch), &f);
}

static void emit_done(struct srv_chan *ch, uint32_t abort)
{
	co_event ev = { .kind = CO_EV_SDO_SERVER_DONE };

	ev.u.sdo_srv.channel = ch->num;
	ev.u.sdo_srv.upload = ch->upload;
	ev.u.sdo_srv.index = ch->index;
	ev.u.sdo_srv.sub = ch->sub;
	ev.u.sdo_srv.mode = ch->mode;
	ev.u.sdo_srv.abort = abort;
	ev.u.sdo_srv.size = ch->upload ? ch->size : ch->offset;
	co_node_emit(node_of(ch), &ev);
}

static void chan_apply(struct srv_chan *ch);

/* The transfer ends with `abort` (0 = success): back to idle, whose
 * on_enter reports CO_EV_SDO_SERVER_DONE once the channel is idle. */
static int finish(struct srv_chan *ch, uint32_t abort)
{
	ch->done_pending = true;
	ch->done_abort = abort;
	return SS_IDLE;
}

static int abort_transfer(struct srv_chan *ch, uint32_t code)
{
	uint8_t p[4];

	co_put_le32(p, code);
	send_mux(ch, SDO_CCS_ABORT << 5, p);
	return finish(ch, code);
}

/* Index/sub of a new request, and the access check for it. */
static uint32_t open_entry(struct srv_chan *ch, const uint8_t *d, bool upload, uint8_t mode)
{
	uint32_t ab;

	ch->index = co_get_le16(&d[1]);
	ch->sub = d[3];
	ch->upload = upload;
	ch->mode = mode;
	ch->offset = 0;
	ch->size = 0;
	ch->toggle = 0;
	sdo_blk_rx_reset(&ch->brx);
	ch->e = co_od_find_ex(node_of(ch)->od, ch->index, ch->sub, &ab);
	if (!ch->e)
		return ab;
	if (upload && !(ch->e->access & CO_ACC_READ))
		return SDO_AB_WRITE_ONLY;
	if (!upload && (!(ch->e->access & CO_ACC_WRITE) || (ch->e->access & CO_ACC_CONST)))
		return SDO_AB_READ_ONLY;
	return 0;
}

static co_od_access access_of(const struct srv_chan *ch, const uint8_t *data, uint32_t size)
{
	co_od_access a = {
		.origin = CO_OD_ORIGIN_SDO, .channel = ch->num, .data = data, .size = size
	};
	return a;
}

/* A hook answers later (sdo_server_continue): wait in "deferred". */
static int park(struct srv_chan *ch, uint8_t kind)
{
	ch->defer = kind;
	return SS_DEFERRED;
}

/* ---- download ----------------------------------------------------------- */

/* Check an announced size against the entry and pick the data path. */
static uint32_t dn_prepare(struct srv_chan *ch, bool size_ind, uint32_t size, bool force_stage)
{
	co_od_entry *e = ch->e;

	ch->size_ind = size_ind;
	ch->size = size;
	if (size_ind) {
		if (size > e->max_size)
			return SDO_AB_LEN_HIGH;
		if (!co_type_is_variable((co_type)e->type) && size < e->size)
			return SDO_AB_LEN_LOW;
	}
	/* Expedited data (<= 4 bytes) always fits the stage (>= 8 bytes). */
	ch->in_place = !force_stage && e->max_size > cfg_of(ch)->sdo_stage_size;
	ch->dst = ch->in_place ? e->data : ch->stage;
	ch->dst_cap = e->max_size;
	if (ch->in_place && e->hooks && e->hooks->check_write) {
		co_od_access a = access_of(ch, NULL, size_ind ? size : 0);
		return e->hooks->check_write(e->hook_ctx, e, &a);
	}
	return 0;
}

/* Store `len` bytes at the current offset; false if they do not fit. */
static bool dn_put(struct srv_chan *ch, const uint8_t *data, uint32_t len)
{
	if (len > ch->dst_cap - ch->offset)
		return false;
	memcpy(ch->dst + ch->offset, data, len);
	ch->offset += len;
	return true;
}

/* Store the checked value, confirm with `resp` and finish. */
static int dn_commit(struct srv_chan *ch, const co_frame *resp, uint32_t len)
{
	co_od_access a = access_of(ch, ch->dst, len);
	co_frame r = *resp; /* `resp` may be ch->pending */
	co_event ev = { .kind = CO_EV_OD_WRITTEN };

	co_od_commit(ch->e, ch->dst, len, &a);
	co_node_send(node_of(ch), &r);
	ev.u.od.index = ch->index;
	ev.u.od.sub = ch->sub;
	ev.u.od.channel = ch->num;
	ev.u.od.size = len;
	co_node_emit(node_of(ch), &ev);
	return finish(ch, 0);
}

/* All data is in: final checks, hook, store, confirm with `resp`. */
static int dn_complete(struct srv_chan *ch, const co_frame *resp)
{
	co_od_entry *e = ch->e;
	uint32_t len = ch->offset;
	uint32_t ab;

	if (ch->size_ind && len != ch->size)
		return abort_transfer(ch, SDO_AB_TYPE_LEN);
	ab = co_od_check_value(e, ch->dst, len);
	if (!ab && e->hooks) {
		co_od_access a = access_of(ch, ch->dst, len);
		if (!ch->in_place && e->hooks->check_write)
			ab = e->hooks->check_write(e->hook_ctx, e, &a);
		else if (ch->in_place && e->hooks->check_streamed)
			ab = e->hooks->check_streamed(e->hook_ctx, e, &a);
	}
	if (ab == CO_OD_DEFERRED) {
		ch->pending = *resp;
		ch->stage_len = len;
		return park(ch, DEFER_COMMIT);
	}
	if (ab)
		return abort_transfer(ch, ab);
	return dn_commit(ch, resp, len);
}

/* Send `pending` and go on to `next`, or park if the hook deferred. */
static int dn_proceed(struct srv_chan *ch, uint32_t ab, uint8_t next)
{
	if (ab == CO_OD_DEFERRED) {
		ch->resume_state = next;
		return park(ch, DEFER_PROCEED);
	}
	if (ab)
		return abort_transfer(ch, ab);
	co_node_send(node_of(ch), &ch->pending);
	return next;
}

static int dn_expedited(struct srv_chan *ch, const uint8_t *d)
{
	co_od_entry *e = ch->e;
	bool s = d[0] & SDO_SIZE_IND;
	uint32_t len = s ? 4u - ((d[0] >> 2) & 3u) : 4u;
	co_frame resp;
	uint32_t ab;

	/* Size not indicated: the object's own size, if it fits in 4 bytes. */
	if (!s && !co_type_is_variable((co_type)e->type) && e->size <= 4)
		len = e->size;
	/* Lenient mode: tolerate clients that always send 4 bytes (the
	 * 0x2B/0x23 confusion of printed device sheets, docs/cosim.md) as long as the surplus bytes are zero. */
	if (cfg_of(ch)->sdo_server_lenient_size && s && !co_type_is_variable((co_type)e->type) &&
	    len > e->size) {
		bool zero = true;
		for (uint32_t i = e->size; i < len; i++)
			zero = zero && d[4 + i] == 0;
		if (zero)
			len = e->size;
	}
	ab = dn_prepare(ch, true, len, true);
	if (ab)
		return abort_transfer(ch, ab);
	ch->mode = SDO_MODE_EXPEDITED;
	dn_put(ch, &d[4], len);
	frame_init(ch, &resp, SDO_SCS_DN_INIT << 5);
	co_put_le16(&resp.data[1], ch->index);
	resp.data[3] = ch->sub;
	return dn_complete(ch, &resp);
}

static int dn_init(struct srv_chan *ch, const uint8_t *d)
{
	uint32_t ab = open_entry(ch, d, false, SDO_MODE_SEGMENTED);

	if (ab)
		return abort_transfer(ch, ab);
	if (d[0] & SDO_EXPEDITED)
		return dn_expedited(ch, d);
	ab = dn_prepare(ch, d[0] & SDO_SIZE_IND, co_get_le32(&d[4]), false);
	frame_init(ch, &ch->pending, SDO_SCS_DN_INIT << 5);
	co_put_le16(&ch->pending.data[1], ch->index);
	ch->pending.data[3] = ch->sub;
	return dn_proceed(ch, ab, SS_DN_SEG);
}

static int dn_seg_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct srv_chan *ch = obj;
	const uint8_t *d = f->data;
	uint8_t t = d[0] & SDO_TOGGLE;
	uint32_t len = SDO_SEG_DATA - ((d[0] >> 1) & 7u);
	co_frame resp;

	(void)now_us;
	if (SDO_CS(d[0]) != SDO_CCS_DN_SEG)
		return abort_transfer(ch, SDO_AB_CMD);
	if (t != ch->toggle)
		return abort_transfer(ch, SDO_AB_TOGGLE);
	if (ch->size_ind && len > ch->size - ch->offset)
		return abort_transfer(ch, SDO_AB_TYPE_LEN);
	if (!dn_put(ch, &d[1], len))
		return abort_transfer(ch, SDO_AB_LEN_HIGH);
	frame_init(ch, &resp, (uint8_t)((SDO_SCS_DN_SEG << 5) | t));
	ch->toggle ^= SDO_TOGGLE;
	if (d[0] & SDO_SEG_LAST)
		return dn_complete(ch, &resp);
	co_node_send(node_of(ch), &resp);
	arm(ch);
	return CO_FSM_STAY;
}

/* ---- block download ------------------------------------------------------ */

static int blk_dn_init(struct srv_chan *ch, const uint8_t *d)
{
	uint32_t ab = open_entry(ch, d, false, SDO_MODE_BLOCK);

	if (!ab && cfg_of(ch)->sdo_server_no_block)
		ab = SDO_AB_CMD;
	if (!ab && (d[0] & 1u)) /* cs must be "initiate" */
		ab = SDO_AB_CMD;
	if (ab)
		return abort_transfer(ch, ab);
	ab = dn_prepare(ch, d[0] & SDO_BLK_SIZE_IND, co_get_le32(&d[4]), false);
	/* The CRC is used only if both ends support it (CiA 301 §7.2.4.3.9):
	 * answer sc = cc, i.e. exactly what this transfer will use. */
	sdo_blk_rx_start(&ch->brx, cfg_of(ch)->sdo_server_blksize, d[0] & SDO_BLK_CRC);
	frame_init(ch, &ch->pending,
		   (uint8_t)((SDO_SCS_BLK_DN << 5) | (d[0] & SDO_BLK_CRC) | SDO_BLK_INIT));
	co_put_le16(&ch->pending.data[1], ch->index);
	ch->pending.data[3] = ch->sub;
	ch->pending.data[4] = ch->brx.blksize;
	return dn_proceed(ch, ab, SS_BLK_DN_SUB);
}

static int blk_dn_ack(struct srv_chan *ch)
{
	co_frame f;

	frame_init(ch, &f, 0);
	sdo_blk_rx_ack(&ch->brx, f.data);
	co_node_send(node_of(ch), &f);
	return ch->brx.last_seen ? SS_BLK_DN_END : SS_BLK_DN_SUB;
}

/* Store an in-sequence segment straight into the destination; an abort
 * code if it does not fit. */
static uint32_t blk_dn_store(struct srv_chan *ch, const uint8_t *d)
{
	uint32_t room = ch->dst_cap - ch->offset;

	if (!ch->brx.last_seen) {
		if (room < SDO_SEG_DATA)
			return SDO_AB_LEN_HIGH;
		memcpy(ch->dst + ch->offset, &d[1], SDO_SEG_DATA);
		ch->offset += SDO_SEG_DATA;
		return 0;
	}
	/* Padding is only known at the end request (n). */
	ch->last_off = ch->offset;
	memcpy(ch->dst + ch->offset, &d[1], room < SDO_SEG_DATA ? room : SDO_SEG_DATA);
	ch->offset += SDO_SEG_DATA; /* virtual until n is known */
	return 0;
}

/* Sequence rules, duplicates and CRC: sdo_block.c. */
static int blk_dn_sub_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct srv_chan *ch = obj;
	const uint8_t *d = f->data;
	unsigned act;
	uint32_t ab;

	(void)now_us;
	if (sdo_blk_seg_is_abort(d))
		return finish(ch, co_get_le32(&d[4]));
	act = sdo_blk_rx_segment(&ch->brx, d);
	if (act & SDO_BLK_RX_BAD_SEQ)
		return abort_transfer(ch, SDO_AB_SEQ);
	if ((act & SDO_BLK_RX_STORE) && (ab = blk_dn_store(ch, d)) != 0)
		return abort_transfer(ch, ab);
	if (act & SDO_BLK_RX_ACK)
		return blk_dn_ack(ch);
	arm(ch);
	return CO_FSM_STAY;
}

static int blk_dn_end_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct srv_chan *ch = obj;
	const uint8_t *d = f->data;
	uint32_t last_len;
	co_frame resp;

	(void)now_us;
	if (sdo_blk_rx_is_dup(&ch->brx, d)) { /* the last segment, delivered twice */
		arm(ch);
		return CO_FSM_STAY;
	}
	if (!sdo_blk_rx_end(d, &last_len))
		return abort_transfer(ch, SDO_AB_CMD);
	ch->offset = ch->last_off + last_len;
	if (ch->offset > ch->dst_cap)
		return abort_transfer(ch, SDO_AB_LEN_HIGH);
	if (!sdo_blk_rx_crc_ok(&ch->brx, d, last_len))
		return abort_transfer(ch, SDO_AB_CRC);
	frame_init(ch, &resp, (uint8_t)((SDO_SCS_BLK_DN << 5) | SDO_BLK_END));
	return dn_complete(ch, &resp);
}

/* ---- upload ------------------------------------------------------------- */

static int up_start_normal(struct srv_chan *ch)
{
	uint8_t p[4] = { 0 };

	if (ch->size >= 1 && ch->size <= SDO_EXP_DATA) {
		ch->mode = SDO_MODE_EXPEDITED;
		memcpy(p, ch->src, ch->size); /* 1..4 bytes */
		send_mux(ch,
			 (uint8_t)((SDO_SCS_UP_INIT << 5) | ((4u - ch->size) << 2) | SDO_EXPEDITED |
				   SDO_SIZE_IND),
			 p);
		return finish(ch, 0);
	}
	ch->mode = SDO_MODE_SEGMENTED;
	co_put_le32(p, ch->size);
	send_mux(ch, (SDO_SCS_UP_INIT << 5) | SDO_SIZE_IND, p);
	ch->toggle = 0;
	return SS_UP_SEG;
}

static int up_start_block(struct srv_chan *ch)
{
	uint8_t p[4];

	/* Protocol switch threshold: small values go the cheaper way. */
	if (ch->pst && ch->size <= ch->pst)
		return up_start_normal(ch);
	ch->mode = SDO_MODE_BLOCK;
	ch->blk_start = 0;
	co_put_le32(p, ch->size);
	/* sc = 1 only if the client asked for a CRC (cc = 1): a client that
	 * did not ask may reject an end frame that announces one. */
	send_mux(ch,
		 (uint8_t)((SDO_SCS_BLK_UP << 5) | (ch->btx.crc_on ? SDO_BLK_CRC : 0) |
			   SDO_BLK_SIZE_IND),
		 p);
	return SS_BLK_UP_START;
}

/* An upload of the entry's own value sends a copy taken now when it fits
 * the stage: a value changed while the transfer runs (between segments,
 * before a block's CRC) goes out whole, as it was at the request. */
static void up_source(struct srv_chan *ch)
{
	bool copy = ch->e->size <= cfg_of(ch)->sdo_stage_size;

	ch->size = ch->e->size;
	ch->src = copy ? memcpy(ch->stage, ch->e->data, ch->e->size) : ch->e->data;
}

static int up_begin(struct srv_chan *ch, bool block)
{
	co_od_entry *e = ch->e;
	uint32_t ab = 0;

	if (e->hooks && e->hooks->read) {
		co_od_access a = access_of(ch, NULL, 0);
		ab = e->hooks->read(e->hook_ctx, e, &a);
	}
	if (ab == CO_OD_DEFERRED) {
		ch->defer_block = block;
		return park(ch, DEFER_READ);
	}
	if (ab)
		return abort_transfer(ch, ab);
	up_source(ch);
	return block ? up_start_block(ch) : up_start_normal(ch);
}

static int up_init(struct srv_chan *ch, const uint8_t *d)
{
	uint32_t ab = open_entry(ch, d, true, SDO_MODE_SEGMENTED);

	if (!ab && d[0] != (SDO_CCS_UP_INIT << 5))
		ab = SDO_AB_CMD;
	if (ab)
		return abort_transfer(ch, ab);
	return up_begin(ch, false);
}

static int up_seg_on_frame(void *obj, const co_frame *fr, uint64_t now_us)
{
	struct srv_chan *ch = obj;
	const uint8_t *d = fr->data;
	uint8_t t = d[0] & SDO_TOGGLE;
	uint32_t left = ch->size - ch->offset;
	uint32_t len = left < SDO_SEG_DATA ? left : SDO_SEG_DATA;
	bool last = left <= SDO_SEG_DATA;
	co_frame f;

	(void)now_us;
	if (SDO_CS(d[0]) != SDO_CCS_UP_SEG)
		return abort_transfer(ch, SDO_AB_CMD);
	if (t != ch->toggle)
		return abort_transfer(ch, SDO_AB_TOGGLE);
	frame_init(ch, &f,
		   (uint8_t)((SDO_SCS_UP_SEG << 5) | t | ((SDO_SEG_DATA - len) << 1) |
			     (last ? SDO_SEG_LAST : 0)));
	if (len)
		memcpy(&f.data[1], ch->src + ch->offset, len);
	co_node_send(node_of(ch), &f);
	ch->offset += len;
	ch->toggle ^= SDO_TOGGLE;
	if (last)
		return finish(ch, 0);
	arm(ch);
	return CO_FSM_STAY;
}

/* ---- block upload ------------------------------------------------------- */

static int blk_up_init(struct srv_chan *ch, const uint8_t *d)
{
	uint32_t ab = open_entry(ch, d, true, SDO_MODE_BLOCK);

	if (!ab && cfg_of(ch)->sdo_server_no_block)
		ab = SDO_AB_CMD;
	if (!ab && (d[0] & 3u) != SDO_BLK_INIT)
		ab = SDO_AB_CMD;
	if (!ab && !sdo_blk_size_valid(d[4]))
		ab = SDO_AB_BLK_SIZE;
	if (ab)
		return abort_transfer(ch, ab);
	sdo_blk_tx_start(&ch->btx, d[4], d[0] & SDO_BLK_CRC);
	ch->pst = d[5];
	return up_begin(ch, true);
}

/* Send one sub-block from blk_start (first time or again after an ack
 * that named an earlier segment), then wait for its ack. */
static int blk_up_send(struct srv_chan *ch)
{
	const uint8_t *data = ch->src + ch->blk_start;
	uint8_t segs = sdo_blk_tx_sub_block(&ch->btx, ch->size - ch->blk_start, true);
	co_frame f;

	for (uint8_t seq = 1; seq <= segs; seq++) {
		frame_init(ch, &f, 0);
		sdo_blk_tx_segment(&ch->btx, seq, data, f.data);
		co_node_send(node_of(ch), &f);
	}
	return SS_BLK_UP_ACK;
}

static int blk_up_start_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct srv_chan *ch = obj;

	(void)now_us;
	if (f->data[0] != ((SDO_CCS_BLK_UP << 5) | SDO_BLK_START))
		return abort_transfer(ch, SDO_AB_CMD);
	return blk_up_send(ch);
}

static int blk_up_ack_on_frame(void *obj, const co_frame *fr, uint64_t now_us)
{
	struct srv_chan *ch = obj;
	uint32_t acked;
	bool done;
	uint32_t ab = sdo_blk_tx_ack(&ch->btx, fr->data, ch->src + ch->blk_start, &acked, &done);
	co_frame f;

	(void)now_us;
	if (ab)
		return abort_transfer(ch, ab);
	ch->blk_start += acked;
	ch->offset = ch->blk_start;
	if (!done)
		return blk_up_send(ch);
	frame_init(ch, &f, 0);
	sdo_blk_tx_end(&ch->btx, f.data);
	co_node_send(node_of(ch), &f);
	return SS_BLK_UP_END;
}

static int blk_up_end_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct srv_chan *ch = obj;

	(void)now_us;
	if (f->data[0] != ((SDO_CCS_BLK_UP << 5) | SDO_BLK_END))
		return abort_transfer(ch, SDO_AB_CMD);
	return finish(ch, 0);
}

/* ---- idle, routed, deferred -------------------------------------------------- */

/* Idle: no timer; report the transfer that just ended (if one did). The
 * event comes once the channel is idle, so its observer may start the
 * next transfer or look at the channel. */
static int idle_on_enter(void *obj, uint64_t now_us)
{
	struct srv_chan *ch = obj;

	(void)now_us;
	ch->deadline = CO_NO_DEADLINE;
	if (!ch->done_pending)
		return CO_FSM_STAY;
	ch->done_pending = false;
	emit_done(ch, ch->done_abort);
	if (ch->reapply) {
		ch->reapply = false;
		chan_apply(ch);
	}
	return CO_FSM_STAY;
}

static int idle_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct srv_chan *ch = obj;
	const uint8_t *d = f->data;

	(void)now_us;
	if (SDO_CS(d[0]) == SDO_CS_NETWORK && ch->srv->route) {
		/* CiA 302-7 network indication: the routing hook takes it
		 * (routed_on_enter). */
		ch->index = co_get_le16(&d[1]);
		ch->sub = d[3];
		ch->route_ind = *f;
		return SS_ROUTED;
	}
	switch (SDO_CS(d[0])) {
	case SDO_CCS_DN_INIT:
		return dn_init(ch, d);
	case SDO_CCS_UP_INIT:
		return up_init(ch, d);
	case SDO_CCS_BLK_DN:
		return blk_dn_init(ch, d);
	case SDO_CCS_BLK_UP:
		return blk_up_init(ch, d);
	case SDO_CCS_ABORT:
		return CO_FSM_STAY; /* nothing to abort */
	default:
		ch->index = co_get_le16(&d[1]);
		ch->sub = d[3];
		return abort_transfer(ch, SDO_AB_CMD);
	}
}

/* Every state of a transfer: the per-frame timeout runs. */
static int transfer_on_enter(void *obj, uint64_t now_us)
{
	(void)now_us;
	arm(obj);
	return CO_FSM_STAY;
}

static int transfer_on_timeout(void *obj, uint64_t now_us)
{
	(void)now_us;
	return abort_transfer(obj, SDO_AB_TIMEOUT);
}

/* Command specifier 7: a CiA 302-7 network indication. The routing hook
 * takes the channel (it answers, confirms or refuses, through
 * sdo_server_route_send), or refuses with an abort code. A routed
 * channel's timers are the routing session's. */
static int routed_on_enter(void *obj, uint64_t now_us)
{
	struct srv_chan *ch = obj;
	struct sdo_server *srv = ch->srv;
	uint8_t p[4];
	uint32_t ab;

	(void)now_us;
	ch->deadline = CO_NO_DEADLINE;
	ab = srv->route->indication(srv->route_ctx, ch->num, ch->route_ind.data,
				    node_of(ch)->now_us);
	if (!ab || state_of(ch) != SS_ROUTED)
		return CO_FSM_STAY;
	co_put_le32(p, ab);
	send_mux(ch, SDO_CCS_ABORT << 5, p);
	return SS_IDLE; /* no transfer began: no DONE event */
}

/* While a hook owns the answer, the client may only abort. */
static int deferred_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	(void)f;
	(void)now_us;
	return abort_transfer(obj, SDO_AB_CMD);
}

/* The hook's answer (sdo_server_continue). */
struct srv_con {
	uint32_t abort;
	const uint8_t *data;
	uint32_t size;
};

static int deferred_on_con(void *obj, const void *con, uint64_t now_us)
{
	struct srv_chan *ch = obj;
	const struct srv_con *c = con;

	(void)now_us;
	if (c->abort)
		return abort_transfer(ch, c->abort);
	switch (ch->defer) {
	case DEFER_COMMIT:
		return dn_commit(ch, &ch->pending, ch->stage_len);
	case DEFER_PROCEED:
		co_node_send(node_of(ch), &ch->pending);
		return ch->resume_state;
	case DEFER_READ:
	default:
		up_source(ch);
		if (c->data) {
			ch->src = c->data;
			ch->size = c->size;
		}
		return ch->defer_block ? up_start_block(ch) : up_start_normal(ch);
	}
}

/* ---- the machine ------------------------------------------------------------- */

#define TRANSFER_STATE(nm, frame_fn)                                             \
	{                                                                        \
		.name = nm, .on_enter = transfer_on_enter, .on_frame = frame_fn, \
		.on_timeout = transfer_on_timeout                                \
	}

static const co_fsm_state srv_states[SS_COUNT] = {
	[SS_IDLE] = { .name = "idle", .on_enter = idle_on_enter, .on_frame = idle_on_frame },
	[SS_DN_SEG] = TRANSFER_STATE("download segment", dn_seg_on_frame),
	[SS_UP_SEG] = TRANSFER_STATE("upload segment", up_seg_on_frame),
	[SS_BLK_DN_SUB] = TRANSFER_STATE("block download sub-block", blk_dn_sub_on_frame),
	[SS_BLK_DN_END] = TRANSFER_STATE("block download end", blk_dn_end_on_frame),
	[SS_BLK_UP_START] = TRANSFER_STATE("block upload start", blk_up_start_on_frame),
	[SS_BLK_UP_ACK] = TRANSFER_STATE("block upload ack", blk_up_ack_on_frame),
	[SS_BLK_UP_END] = TRANSFER_STATE("block upload end", blk_up_end_on_frame),
	[SS_DEFERRED] = { .name = "deferred",
			  .on_enter = transfer_on_enter,
			  .on_frame = deferred_on_frame,
			  .on_timeout = transfer_on_timeout,
			  .on_con = deferred_on_con },
	/* Routed frames never reach the table (srv_rx hands them over). */
	[SS_ROUTED] = { .name = "routed", .on_enter = routed_on_enter },
};

static const co_fsm_def srv_def = {
	.name = "sdo_server",
	.states = srv_states,
	.n_states = SS_COUNT,
};

const char *sdo_server_state_to_string(const co_node *node, uint8_t channel)
{
	const struct sdo_server *srv = node->sdo_srv;

	if (!srv || channel >= srv->n)
		return "?";
	return co_fsm_state_name(&srv_def, state_of(&srv->ch[channel]));
}

static void srv_rx(co_node *node, void *arg, const co_frame *f, uint64_t now_us)
{
	struct srv_chan *ch = arg;
	int st = state_of(ch);

	/* CiA 301 SDO frames always have 8 data bytes; ignore anything else
	 * (an RTR or a short frame cannot be answered meaningfully). */
	if (f->len != 8 || (f->flags & CO_FRAME_RTR))
		return;
	/* CiA 301 §7.3.2.2 (services per NMT state): STOPPED allows only NMT
	 * and error control, so no SDO answer at all, not even an abort. */
	if (co_nmt_get_state(node) == CO_NMT_STOPPED)
		return;
	if (st == SS_ROUTED) {
		if (ch->srv->route->frame(ch->srv->route_ctx, ch->num, f->data, now_us) ||
		    state_of(ch) != SS_IDLE)
			return;
		st = SS_IDLE; /* a new request after a route that just ended */
	}
	if (st != SS_IDLE && st != SS_BLK_DN_SUB && SDO_CS(f->data[0]) == SDO_CCS_ABORT &&
	    !sdo_blk_rx_is_dup(&ch->brx, f->data)) {
		co_fsm_goto(&ch->fsm, finish(ch, co_get_le32(&f->data[4])), now_us);
		return;
	}
	co_fsm_frame(&ch->fsm, f, now_us);
}

/* ---- deferred answers ---------------------------------------------------- */

int sdo_server_continue(co_node *node, uint8_t channel, uint32_t abort, const uint8_t *data,
			uint32_t size, uint64_t now_us)
{
	struct sdo_server *srv = node->sdo_srv;
	struct srv_con con = { .abort = abort, .data = data, .size = size };
	struct srv_chan *ch;

	if (!srv || channel >= srv->n)
		return -EINVAL;
	ch = &srv->ch[channel];
	if (state_of(ch) != SS_DEFERRED)
		return -ENOENT;
	node->now_us = now_us;
	co_fsm_con(&ch->fsm, &con, now_us);
	return 0;
}

/* ---- CiA 302-7 routing hook ---------------------------------------------- */

int sdo_server_route_attach(co_node *node, const sdo_server_route_ops *ops, void *ctx)
{
	struct sdo_server *srv = node->sdo_srv;

	if (!srv || (ops && (!ops->indication || !ops->frame || !ops->ended)))
		return -EINVAL;
	for (uint8_t i = 0; i < srv->n; i++)
		if (state_of(&srv->ch[i]) == SS_ROUTED)
			return -EBUSY;
	srv->route = ops;
	srv->route_ctx = ctx;
	return 0;
}

static struct srv_chan *routed_chan(co_node *node, uint8_t channel)
{
	struct sdo_server *srv = node->sdo_srv;

	if (!srv || channel >= srv->n || state_of(&srv->ch[channel]) != SS_ROUTED)
		return NULL;
	return &srv->ch[channel];
}

int sdo_server_route_frame(co_node *node, uint8_t channel, const uint8_t d[8], co_frame *out)
{
	struct srv_chan *ch = routed_chan(node, channel);

	if (!ch)
		return -ENOENT;
	frame_init(ch, out, d[0]);
	memcpy(&out->data[1], &d[1], 7);
	return 0;
}

int sdo_server_route_send(co_node *node, uint8_t channel, const uint8_t d[8])
{
	co_frame f;
	int rc = sdo_server_route_frame(node, channel, d, &f);

	return rc ? rc : co_node_send(node, &f);
}

int sdo_server_route_end(co_node *node, uint8_t channel)
{
	struct srv_chan *ch = routed_chan(node, channel);

	if (!ch)
		return -ENOENT;
	co_fsm_goto(&ch->fsm, SS_IDLE, node->now_us);
	if (ch->reapply) {
		ch->reapply = false;
		chan_apply(ch);
	}
	return 0;
}

/* The server itself ends a route (parameters changed, reset): tell the
 * hook, which must not send on the channel any more. */
static void route_drop(struct srv_chan *ch)
{
	co_fsm_goto(&ch->fsm, SS_IDLE, node_of(ch)->now_us);
	ch->srv->route->ended(ch->srv->route_ctx, ch->num);
}

bool sdo_server_busy(const co_node *node, uint8_t channel)
{
	const struct sdo_server *srv = node->sdo_srv;

	return srv && channel < srv->n && state_of(&srv->ch[channel]) != SS_IDLE;
}

uint8_t sdo_server_channel_count(const co_node *node)
{
	return node->sdo_srv ? node->sdo_srv->n : 0;
}

/* ---- channel parameters (1200h..127Fh) ------------------------------------ */

/* Register the receiver for the channel's current COB-IDs. */
static void chan_apply(struct srv_chan *ch)
{
	co_node *node = node_of(ch);
	bool valid = !(ch->cob_rx & SDO_COB_INVALID) && !(ch->cob_tx & SDO_COB_INVALID);

	if (state_of(ch) == SS_ROUTED)
		route_drop(ch);
	else if (state_of(ch) != SS_IDLE) /* parameters changed under a transfer */
		co_fsm_goto(&ch->fsm, finish(ch, SDO_AB_GENERAL), node->now_us);
	if (!valid || co_rx_move(node, ch->rx_handle, ch->cob_rx & CO_FRAME_EFF_MASK,
				 (ch->cob_rx & SDO_COB_EXT) ? CO_FRAME_EXT : 0) != 0)
		co_rx_disable(node, ch->rx_handle);
}

static void chan_load(struct srv_chan *ch)
{
	co_od *od = node_of(ch)->od;
	uint16_t idx = (uint16_t)(SDO_SERVER_PARAM + ch->num);
	uint8_t id = node_of(ch)->node_id;
	uint32_t v;

	if (ch->num == 0) {
		/* 1200h is optional; without it the predefined set applies. */
		bool ok = id >= 1 && id <= 127;
		ch->cob_rx = ok ? SDO_COB_RX_BASE + id : SDO_COB_INVALID;
		ch->cob_tx = ok ? SDO_COB_TX_BASE + id : SDO_COB_INVALID;
	} else {
		ch->cob_rx = ch->cob_tx = SDO_COB_INVALID;
	}
	if (co_od_get_u32(od, idx, 1, &v) == 0)
		ch->cob_rx = v;
	if (co_od_get_u32(od, idx, 2, &v) == 0)
		ch->cob_tx = v;
	chan_apply(ch);
}

static bool cob_valid_form(uint32_t v)
{
	if (v & SDO_COB_EXT)
		return true;
	return (v & 0x1FFFF800u) == 0; /* 11-bit id: nothing in bits 11..28 */
}

/* CiA 301 §7.5.2.33: a valid COB-ID may not be changed to another valid
 * one; the channel has to be made invalid (bit 31) first. */
static uint32_t cob_check(void *ctx, co_od_entry *e, const co_od_access *a)
{
	(void)ctx;
	uint32_t old = (uint32_t)co_od_entry_raw(e);
	uint32_t nv;

	if (!a->data || a->size != 4)
		return SDO_AB_TYPE_LEN;
	nv = co_get_le32(a->data);
	if (!cob_valid_form(nv))
		return SDO_AB_VALUE;
	if (!(old & SDO_COB_INVALID) && !(nv & SDO_COB_INVALID) && nv != old)
		return SDO_AB_VALUE;
	return 0;
}

static void cob_written(void *ctx, co_od_entry *e, const co_od_access *a)
{
	struct srv_chan *ch = ctx;
	uint32_t v = (uint32_t)co_od_entry_raw(e);

	(void)a;
	if (e->sub == 1)
		ch->cob_rx = v;
	else
		ch->cob_tx = v;
	/* The channel answering this very write must confirm it on the old
	 * COB-ID first: its finish() applies the new one. */
	if (a->origin == CO_OD_ORIGIN_SDO && a->channel == ch->num)
		ch->reapply = true;
	else
		chan_apply(ch);
}

static const co_od_hooks cob_hooks = {
	.check_write = cob_check,
	.after_write = cob_written,
};

static int chan_od_init(struct srv_chan *ch)
{
	co_od *od = node_of(ch)->od;
	uint16_t idx = (uint16_t)(SDO_SERVER_PARAM + ch->num);
	int rc;

	/* 1200h is optional (see chan_load()). */
	if (ch->num > 0 && (rc = sdo_param_od_add(od, idx, CO_ACC_RO)))
		return rc;
	for (uint8_t s = 1; s <= 2; s++)
		co_od_set_hooks(od, idx, s, &cob_hooks, ch);
	return 0;
}

/* ---- service ops -------------------------------------------------------- */

static void srv_fini(co_node *node)
{
	struct sdo_server *srv = node->sdo_srv;

	if (!srv)
		return;
	for (uint8_t i = 0; i < srv->n; i++) {
		struct srv_chan *ch = &srv->ch[i];
		uint16_t idx = (uint16_t)(SDO_SERVER_PARAM + i);
		co_od_entry *e;
		for (uint8_t s = 1; s <= 2; s++)
			if ((e = co_od_find(node->od, idx, s)) && e->hook_ctx == ch)
				co_od_entry_set_hooks(e, NULL, NULL);
		if (ch->rx_handle >= 0)
			co_rx_unregister(node, ch->rx_handle);
		free(ch->stage);
	}
	free(srv);
	node->sdo_srv = NULL;
}

static int srv_init(co_node *node)
{
	uint8_t n = node->cfg.sdo_server_count;
	struct sdo_server *srv = calloc(1, sizeof(*srv) + n * sizeof(srv->ch[0]));
	int rc = 0;

	if (!srv)
		return -ENOMEM;
	srv->node = node;
	srv->n = n;
	node->sdo_srv = srv;
	for (uint8_t i = 0; i < n; i++)
		srv->ch[i].rx_handle = -1;
	for (uint8_t i = 0; i < n && !rc; i++) {
		struct srv_chan *ch = &srv->ch[i];
		ch->srv = srv;
		ch->num = i;
		ch->deadline = CO_NO_DEADLINE;
		co_fsm_init(&ch->fsm, &srv_def, ch, SS_IDLE);
		ch->stage = malloc(node->cfg.sdo_stage_size);
		if (!ch->stage) {
			rc = -ENOMEM;
			break;
		}
		/* Register on a placeholder id, then move/disable per COB-ID. */
		ch->rx_handle = co_rx_register(node, 0, 0, srv_rx, ch);
		if (ch->rx_handle < 0) {
			rc = ch->rx_handle;
			break;
		}
		co_rx_disable(node, ch->rx_handle);
		rc = chan_od_init(ch);
		if (!rc)
			chan_load(ch);
	}
	if (rc)
		srv_fini(node);
	return rc;
}

static uint64_t srv_tick(co_node *node, uint64_t now_us)
{
	struct sdo_server *srv = node->sdo_srv;
	uint64_t next = CO_NO_DEADLINE;

	if (!srv)
		return next;
	for (uint8_t i = 0; i < srv->n; i++) {
		struct srv_chan *ch = &srv->ch[i];
		if (state_of(ch) != SS_IDLE && now_us >= ch->deadline)
			co_fsm_timeout(&ch->fsm, now_us);
		if (ch->deadline < next)
			next = ch->deadline;
	}
	return next;
}

static void srv_reset_comm(co_node *node, uint64_t now_us)
{
	struct sdo_server *srv = node->sdo_srv;

	if (!srv)
		return;
	for (uint8_t i = 0; i < srv->n; i++) {
		if (state_of(&srv->ch[i]) == SS_ROUTED)
			route_drop(&srv->ch[i]);
		/* a reset ends transfers silently (no done_pending: no event) */
		co_fsm_goto(&srv->ch[i].fsm, SS_IDLE, now_us);
		chan_load(&srv->ch[i]);
	}
}

/* Entering STOPPED ends every transfer in progress without a frame (no
 * SDO traffic is allowed there); the application sees
 * CO_EV_SDO_SERVER_DONE with 0x08000022 (device state). Requests are
 * ignored in srv_rx() until the node leaves STOPPED. */
static void srv_nmt_changed(co_node *node, uint8_t state, uint64_t now_us)
{
	struct sdo_server *srv = node->sdo_srv;

	if (!srv || state != CO_NMT_STOPPED)
		return;
	for (uint8_t i = 0; i < srv->n; i++) {
		struct srv_chan *ch = &srv->ch[i];
		if (state_of(ch) == SS_ROUTED)
			route_drop(ch);
		else if (state_of(ch) != SS_IDLE)
			co_fsm_goto(&ch->fsm, finish(ch, SDO_AB_DEV_STATE), now_us);
	}
}

const co_service co_svc_sdo_server = {
	.name = "sdo-server",
	.init = srv_init,
	.fini = srv_fini,
	.tick = srv_tick,
	.reset_comm = srv_reset_comm,
	.nmt_changed = srv_nmt_changed,
};
