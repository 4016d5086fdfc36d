/* SPDX-License-Identifier: MIT */
/*
 * SDO client (CiA 301 §7.2.4), the top of its files (core/sdo_client_int.h
 * names them): one core/fsm.h machine per channel, a bounded FIFO of
 * requests in front of it. The table cli_states[] gives each state its
 * frame handler, which returns the next state; all transfer states share
 * one on_enter (the per-frame timer) and one timeout rule
 * (sdo_client_xfer.c).
 *
 * Requests reach a channel from its own FIFO (sdo_client_submit) or from
 * the pool FIFO shared by all channels (sdo_client_pool_submit,
 * sdo_client_pool.c). Whenever a transfer ends, sdo_cli_kick_all() starts
 * what can start: first each idle channel's own FIFO, then pool requests
 * in order on channels that are idle with an empty FIFO, skipping those
 * whose target is busy. Every transfer ends in sdo_cli_complete(), which
 * returns idle; idle's on_enter calls the request's con, then emits the
 * event (a request cancelled before it started is confirmed directly).
 */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "core/nmt.h"
#include "core/sdo_client_int.h"

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
	sdo_cli_kick_all(ch->cli);
	return CO_FSM_STAY;
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
	return sdo_cli_complete(ch, ch->start_abort);
}

static int leased_on_enter(void *obj, uint64_t now_us)
{
	struct cli_chan *ch = obj;

	(void)now_us;
	ch->deadline = CO_NO_DEADLINE; /* the relay keeps its own timers */
	return CO_FSM_STAY;
}

/* ---- the machine ----------------------------------------------------------------- */

#define TRANSFER_STATE(nm, frame_fn)                                                     \
	{                                                                                \
		.name = nm, .on_enter = sdo_cli_transfer_on_enter, .on_frame = frame_fn, \
		.on_timeout = sdo_cli_transfer_on_timeout                                \
	}

/* Frames of a leased channel and of the idle / start failed states never
 * reach the table (cli_rx). */
static const co_fsm_state cli_states[CS_COUNT] = {
	[CS_IDLE] = { .name = "idle", .on_enter = idle_on_enter },
	[CS_DN_INIT] = TRANSFER_STATE("download initiate", sdo_cli_dn_init_on_frame),
	[CS_DN_SEG] = TRANSFER_STATE("download segment", sdo_cli_dn_seg_on_frame),
	[CS_UP_INIT] = TRANSFER_STATE("upload initiate", sdo_cli_up_init_on_frame),
	[CS_UP_SEG] = TRANSFER_STATE("upload segment", sdo_cli_up_seg_on_frame),
	[CS_BLK_DN_INIT] = TRANSFER_STATE("block download initiate", sdo_cli_blk_dn_init_on_frame),
	[CS_BLK_DN_ACK] = TRANSFER_STATE("block download ack", sdo_cli_blk_dn_ack_on_frame),
	[CS_BLK_DN_END] = TRANSFER_STATE("block download end", sdo_cli_blk_dn_end_on_frame),
	[CS_BLK_UP_INIT] = TRANSFER_STATE("block upload initiate", sdo_cli_blk_up_init_on_frame),
	[CS_BLK_UP_SUB] = TRANSFER_STATE("block upload sub-block", sdo_cli_blk_up_sub_on_frame),
	[CS_BLK_UP_END] = TRANSFER_STATE("block upload end", sdo_cli_blk_up_end_on_frame),
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
				: sdo_cli_is_abort(d) && !sdo_blk_rx_is_dup(&ch->brx, d)) {
		co_fsm_goto(&ch->fsm, sdo_cli_server_abort(ch, st, d), now_us);
		return;
	}
	co_fsm_frame(&ch->fsm, f, now_us);
}

int sdo_client_submit(co_node *node, uint8_t channel, const sdo_client_req *req, uint64_t now_us)
{
	struct sdo_client *cli = node->sdo_cli;
	struct cli_chan *ch;
	uint16_t cap;

	if (!cli || channel >= cli->n || !req || !sdo_cli_req_valid(req))
		return -EINVAL;
	ch = &cli->ch[channel];
	cap = node->cfg.sdo_client_queue_len;
	if (ch->q_len >= cap)
		return -ENOSPC;
	node->now_us = now_us;
	ch->q[(ch->q_head + ch->q_len) % cap] = *req;
	ch->q_len++;
	sdo_cli_kick(ch);
	sdo_cli_gate_sync(cli);
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
	co_fsm_goto(&ch->fsm,
		    st == CS_START_FAILED ? sdo_cli_complete(ch, abort)
					  : sdo_cli_abort_local(ch, abort),
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
		sdo_cli_gate_sync(ch->cli); /* its channel may be free now */
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
		if (sdo_cli_pool_at(cli, i)->tag != tag)
			continue;
		sdo_client_req r = *sdo_cli_pool_at(cli, i);
		sdo_cli_pool_remove(cli, i);
		confirm(node, &r, SDO_CLIENT_NO_CHANNEL, r.mode, abort, 0, false);
		return 0;
	}
	return -ENOENT;
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
		sdo_cli_kick_all(
			cli); /* what the gate or a settling server held back; a refusal re-arms */
	}
	sdo_cli_gate_sync(cli); /* servers whose settling time ended */
	next = sdo_cli_gate_next(cli);
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
			co_fsm_goto(&ch->fsm, sdo_cli_complete(ch, SDO_AB_DEV_STATE), now_us);
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
