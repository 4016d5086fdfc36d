/* SPDX-License-Identifier: MIT */
/*
 * SDO client transfers (CiA 301 §7.2.4.3): starting one on a channel and
 * the states of the expedited, segmented and block (with CRC) download and
 * upload machines, each a frame handler that returns the next state.
 *
 * Data never has to be in memory as a whole: downloads read the source
 * sequentially into one sub-block buffer (127 x 7 bytes), which is also
 * what a block retransmission resends; uploads hand each byte to the sink
 * exactly once, in order. The sub-block rules and the CRC are in
 * sdo_block.c, shared with the server.
 */
#include <string.h>

#include "core/nmt.h"
#include "core/sdo_client_int.h"

static void arm(struct cli_chan *ch)
{
	co_node *node = node_of(ch);

	ch->deadline = node->now_us + ch->timeout_us;
	co_node_deadline_lower(node, ch->deadline);
}

void sdo_cli_tx(struct cli_chan *ch, const uint8_t d[8])
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
	sdo_cli_tx(ch, d);
}

static bool mux_matches(const struct cli_chan *ch, const uint8_t *d)
{
	return co_get_le16(&d[1]) == ch->cur.index && d[3] == ch->cur.sub;
}

/* The running request ends with `abort` (0 = success): back to idle,
 * whose on_enter confirms it and starts what waits. */
int sdo_cli_complete(struct cli_chan *ch, uint32_t abort)
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

int sdo_cli_abort_local(struct cli_chan *ch, uint32_t code)
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
	return sdo_cli_complete(ch, code);
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
bool sdo_cli_is_abort(const uint8_t *d)
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
		return sdo_cli_abort_local(ch, SDO_AB_STORE);
	d[0] = (uint8_t)((SDO_CCS_DN_SEG << 5) | ch->toggle | ((SDO_SEG_DATA - len) << 1) |
			 (last ? SDO_SEG_LAST : 0));
	sdo_cli_tx(ch, d);
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
		sdo_cli_tx(ch, d);
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

int sdo_cli_dn_init_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct cli_chan *ch = obj;
	const uint8_t *d = f->data;

	(void)now_us;
	if (d[0] != (SDO_SCS_DN_INIT << 5))
		return sdo_cli_abort_local(ch, SDO_AB_CMD);
	if (!mux_matches(ch, d))
		return sdo_cli_abort_local(ch, SDO_AB_PARAM_INCOMPAT);
	if (ch->mode == SDO_MODE_EXPEDITED) {
		ch->offset = ch->total;
		return sdo_cli_complete(ch, 0);
	}
	return dn_send_segment(ch);
}

int sdo_cli_dn_seg_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct cli_chan *ch = obj;
	const uint8_t *d = f->data;

	(void)now_us;
	if (SDO_CS(d[0]) != SDO_SCS_DN_SEG)
		return sdo_cli_abort_local(ch, SDO_AB_CMD);
	if ((d[0] & SDO_TOGGLE) != ch->toggle)
		return sdo_cli_abort_local(ch, SDO_AB_TOGGLE);
	ch->offset = ch->read_off;
	if (ch->offset >= ch->total)
		return sdo_cli_complete(ch, 0);
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
		return sdo_cli_abort_local(ch, SDO_AB_STORE);
	segs = sdo_blk_tx_sub_block(&ch->btx, ch->sub_len, ch->read_off == ch->total);
	for (uint8_t seq = 1; seq <= segs; seq++) {
		sdo_blk_tx_segment(&ch->btx, seq, ch->sub_buf, d);
		sdo_cli_tx(ch, d);
	}
	return CS_BLK_DN_ACK;
}

int sdo_cli_blk_dn_init_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct cli_chan *ch = obj;
	const uint8_t *d = f->data;

	(void)now_us;
	if ((d[0] & 0xE3u) != (SDO_SCS_BLK_DN << 5 | SDO_BLK_INIT))
		return sdo_cli_abort_local(ch, SDO_AB_CMD);
	if (!mux_matches(ch, d))
		return sdo_cli_abort_local(ch, SDO_AB_PARAM_INCOMPAT);
	if (!sdo_blk_size_valid(d[4]))
		return sdo_cli_abort_local(ch, SDO_AB_BLK_SIZE);
	/* we asked for CRC; the server decides */
	sdo_blk_tx_start(&ch->btx, d[4], d[0] & SDO_BLK_CRC);
	return blk_dn_send(ch);
}

int sdo_cli_blk_dn_ack_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct cli_chan *ch = obj;
	uint32_t acked;
	bool done;
	uint32_t ab = sdo_blk_tx_ack(&ch->btx, f->data, ch->sub_buf, &acked, &done);

	(void)now_us;
	if (ab)
		return sdo_cli_abort_local(ch, ab);
	if (done) {
		uint8_t e[8];
		ch->offset = ch->total;
		sdo_blk_tx_end(&ch->btx, e);
		sdo_cli_tx(ch, e);
		return CS_BLK_DN_END;
	}
	/* Keep what was not acknowledged; it goes out again first. */
	memmove(ch->sub_buf, ch->sub_buf + acked, ch->sub_len - acked);
	ch->sub_len -= acked;
	ch->offset += acked;
	return blk_dn_send(ch);
}

int sdo_cli_blk_dn_end_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct cli_chan *ch = obj;

	(void)now_us;
	if (f->data[0] != ((SDO_SCS_BLK_DN << 5) | SDO_BLK_END))
		return sdo_cli_abort_local(ch, SDO_AB_CMD);
	return sdo_cli_complete(ch, 0);
}

/* ---- upload ------------------------------------------------------------- */

static int up_request_segment(struct cli_chan *ch)
{
	uint8_t d[8] = { (uint8_t)((SDO_CCS_UP_SEG << 5) | ch->toggle) };

	sdo_cli_tx(ch, d);
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
		sdo_cli_tx(ch, d);
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
		return ab ? sdo_cli_abort_local(ch, ab) : sdo_cli_complete(ch, 0);
	}
	ch->mode = SDO_MODE_SEGMENTED;
	if (d[0] & SDO_SIZE_IND) {
		ch->total = co_get_le32(&d[4]);
		if (ch->cur.buf && ch->total > ch->cur.cap)
			return sdo_cli_abort_local(ch, SDO_AB_NO_MEM);
	}
	ch->toggle = 0;
	return up_request_segment(ch);
}

int sdo_cli_up_init_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct cli_chan *ch = obj;
	const uint8_t *d = f->data;

	(void)now_us;
	if ((d[0] & 0xF0u) != (SDO_SCS_UP_INIT << 5))
		return sdo_cli_abort_local(ch, SDO_AB_CMD);
	if (!mux_matches(ch, d))
		return sdo_cli_abort_local(ch, SDO_AB_PARAM_INCOMPAT);
	return up_init_resp(ch, d);
}

int sdo_cli_up_seg_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct cli_chan *ch = obj;
	const uint8_t *d = f->data;
	uint32_t len = SDO_SEG_DATA - ((d[0] >> 1) & 7u);
	uint32_t ab;

	(void)now_us;
	if (SDO_CS(d[0]) != SDO_SCS_UP_SEG)
		return sdo_cli_abort_local(ch, SDO_AB_CMD);
	if ((d[0] & SDO_TOGGLE) != ch->toggle)
		return sdo_cli_abort_local(ch, SDO_AB_TOGGLE);
	ab = sink_put(ch, &d[1], len);
	if (!ab && (d[0] & SDO_SEG_LAST) && ch->total != UNKNOWN_SIZE && ch->offset != ch->total)
		ab = SDO_AB_TYPE_LEN;
	if (ab)
		return sdo_cli_abort_local(ch, ab);
	if (d[0] & SDO_SEG_LAST)
		return sdo_cli_complete(ch, 0);
	ch->toggle ^= SDO_TOGGLE;
	return up_request_segment(ch);
}

/* ---- block upload ------------------------------------------------------- */

int sdo_cli_blk_up_init_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct cli_chan *ch = obj;
	const uint8_t *d = f->data;
	uint8_t start[8] = { (SDO_CCS_BLK_UP << 5) | SDO_BLK_START };

	(void)now_us;
	if (SDO_CS(d[0]) == SDO_SCS_UP_INIT) /* protocol switch */
		return mux_matches(ch, d) ? up_init_resp(ch, d)
					  : sdo_cli_abort_local(ch, SDO_AB_PARAM_INCOMPAT);
	if ((d[0] & 0xE1u) != (SDO_SCS_BLK_UP << 5))
		return sdo_cli_abort_local(ch, SDO_AB_CMD);
	if (!mux_matches(ch, d))
		return sdo_cli_abort_local(ch, SDO_AB_PARAM_INCOMPAT);
	if (d[0] & SDO_BLK_SIZE_IND) {
		ch->total = co_get_le32(&d[4]);
		if (ch->cur.buf && ch->total > ch->cur.cap)
			return sdo_cli_abort_local(ch, SDO_AB_NO_MEM);
	}
	/* blksize: what start_upload() announced */
	sdo_blk_rx_start(&ch->brx, ch->brx.blksize, d[0] & SDO_BLK_CRC);
	ch->pend_valid = false;
	sdo_cli_tx(ch, start);
	return CS_BLK_UP_SUB;
}

static int blk_up_ack(struct cli_chan *ch)
{
	uint8_t d[8];

	sdo_blk_rx_ack(&ch->brx, d);
	sdo_cli_tx(ch, d);
	return ch->brx.last_seen ? CS_BLK_UP_END : CS_BLK_UP_SUB;
}

/* Sequence rules, duplicates and CRC: sdo_block.c, as for the server's
 * block download. Each segment is held back until the next one arrives:
 * the sink must only see data bytes, and the last segment's length is
 * only known at the end request. */
int sdo_cli_blk_up_sub_on_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	struct cli_chan *ch = obj;
	const uint8_t *d = f->data;
	unsigned act = sdo_blk_rx_segment(&ch->brx, d);

	(void)now_us;
	if (act & SDO_BLK_RX_BAD_SEQ)
		return sdo_cli_abort_local(ch, SDO_AB_SEQ);
	if (act & SDO_BLK_RX_STORE) {
		if (ch->pend_valid) {
			uint32_t ab = sink_put(ch, ch->pend, SDO_SEG_DATA);
			if (ab)
				return sdo_cli_abort_local(ch, ab);
		}
		memcpy(ch->pend, &d[1], SDO_SEG_DATA);
		ch->pend_valid = true;
	}
	if (act & SDO_BLK_RX_ACK)
		return blk_up_ack(ch);
	arm(ch);
	return CO_FSM_STAY;
}

int sdo_cli_blk_up_end_on_frame(void *obj, const co_frame *f, uint64_t now_us)
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
		return sdo_cli_abort_local(ch, SDO_AB_CMD);
	if (ch->pend_valid)
		ab = sink_put(ch, ch->pend, last_len);
	if (!ab && ch->total != UNKNOWN_SIZE && ch->offset != ch->total)
		ab = SDO_AB_TYPE_LEN;
	if (!ab && !sdo_blk_rx_crc_ok(&ch->brx, d, last_len))
		ab = SDO_AB_CRC;
	if (ab)
		return sdo_cli_abort_local(ch, ab);
	sdo_cli_tx(ch, resp);
	return sdo_cli_complete(ch, 0);
}

/* Every transfer state: the per-frame timeout runs from here. */
int sdo_cli_transfer_on_enter(void *obj, uint64_t now_us)
{
	(void)now_us;
	arm(obj);
	return CO_FSM_STAY;
}

int sdo_cli_transfer_on_timeout(void *obj, uint64_t now_us)
{
	(void)now_us;
	return sdo_cli_abort_local(obj, SDO_AB_TIMEOUT);
}

/* ---- falling back from block, starting a transfer ----------------------- */

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
int sdo_cli_server_abort(struct cli_chan *ch, int st, const uint8_t *d)
{
	uint32_t code = co_get_le32(&d[4]);
	bool refused = code == SDO_AB_CMD || code == SDO_AB_UNSUPP_ACCESS;

	if (refused && !ch->fell_back && (st == CS_BLK_DN_INIT || st == CS_BLK_UP_INIT))
		return restart_without_block(ch);
	return sdo_cli_complete(ch, code);
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

uint32_t sdo_cli_cob_req(const sdo_client_req *r)
{
	if (r->relay)
		return RELAY_ID | r->relay_target;
	return r->cob_req ? r->cob_req : SDO_COB_RX_BASE + r->node_id;
}

uint32_t sdo_cli_cob_resp(const sdo_client_req *r)
{
	if (r->relay)
		return RELAY_ID | r->relay_target;
	return r->cob_resp ? r->cob_resp : SDO_COB_TX_BASE + r->node_id;
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
void sdo_cli_show_target(struct cli_chan *ch, const sdo_client_req *r)
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
int sdo_cli_start_state(struct cli_chan *ch, const sdo_client_req *r)
{
	co_node *node = node_of(ch);

	ch->cur = *r;
	ch->cob_req = sdo_cli_cob_req(r);
	ch->cob_resp = sdo_cli_cob_resp(r);
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
	sdo_cli_show_target(ch, r);
	/* CiA 301 §7.3.2.2: no SDO in STOPPED; reported from the next tick
	 * like any request that cannot start. */
	if (co_nmt_get_state(node) == CO_NMT_STOPPED)
		return fail_start(ch, SDO_AB_DEV_STATE);
	if (listen_for_answers(ch) != 0)
		return fail_start(ch, SDO_AB_NO_RESOURCE);
	return r->upload ? start_upload(ch) : start_download(ch);
}
