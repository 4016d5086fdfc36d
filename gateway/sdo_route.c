/* SPDX-License-Identifier: MIT */
/*
 * gateway/sdo_route.c - the routed SDO session (sdo_route.h).
 *
 * Each relay state knows whose turn it is; a frame from the other side
 * (other than an abort) is a protocol error that ends the session with
 * 05040001 on both sides, as an SDO server would answer it. Data frames
 * are forwarded unchanged, so the CRC, sizes, toggles and sequence numbers
 * stay the two ends' business: the gateway only needs the command
 * specifiers (CiA 301 §7.2.4.3) to see the end of the transfer:
 *
 *   download  init 001..e. -> 60 [e=1: end]; segment 000t nnnc -> 001t
 *             [c=1: end]
 *   upload    init 40 -> 010. nn e s [e=1: end]; 011t -> 000t nnnc [c=1: end]
 *   block dn  110..0 -> A0; segments c|seq -> A2 ackseq [ackseq >= the
 *             c=1 segment: end phase]; 110nnn01 -> A1 [end]
 *   block up  101..00 -> 110..0 (or 010... when the server switches to a
 *             normal upload); A3 -> segments c|seq; A2 ackseq [>= the c=1
 *             segment: end phase]; 110nnn01 -> A1 [end]
 *   abort     100....., bytes 4..7 = code; inside a sub-block only 80h
 *             (sequence number 0 does not exist there).
 */
#include "gateway/sdo_route.h"

#include <errno.h>
#include <string.h>

#include "core/frame.h"

enum side {
	SIDE_REQUESTER,
	SIDE_TARGET,
	SIDE_BOTH
};

/* Whose frame the state waits for: picks the timeout and its code. */
static const uint8_t waits_for[GW_SR_COUNT] = {
	[GW_SR_HOP] = SIDE_TARGET,
	[GW_SR_WAIT_INIT] = SIDE_REQUESTER,
	[GW_SR_DN_INIT_RESP] = SIDE_TARGET,
	[GW_SR_DN_SEG_REQ] = SIDE_REQUESTER,
	[GW_SR_DN_SEG_RESP] = SIDE_TARGET,
	[GW_SR_UP_INIT_RESP] = SIDE_TARGET,
	[GW_SR_UP_SEG_REQ] = SIDE_REQUESTER,
	[GW_SR_UP_SEG_RESP] = SIDE_TARGET,
	[GW_SR_BLK_DN_INIT_RESP] = SIDE_TARGET,
	[GW_SR_BLK_DN_SUB] = SIDE_BOTH,
	[GW_SR_BLK_DN_END_REQ] = SIDE_REQUESTER,
	[GW_SR_BLK_DN_END_RESP] = SIDE_TARGET,
	[GW_SR_BLK_UP_INIT_RESP] = SIDE_TARGET,
	[GW_SR_BLK_UP_START] = SIDE_REQUESTER,
	[GW_SR_BLK_UP_SUB] = SIDE_BOTH,
	[GW_SR_BLK_UP_END] = SIDE_TARGET,
	[GW_SR_BLK_UP_END_RESP] = SIDE_REQUESTER,
};

#define CS(d) ((uint8_t)((d)[0] >> 5))

/* ---- actions --------------------------------------------------------------- */

static void to_requester(gw_sdo_route *s, const uint8_t d[8])
{
	s->frames_to_requester++;
	s->ops->to_requester(s->ctx, d);
}

static void to_target(gw_sdo_route *s, const uint8_t d[8])
{
	s->frames_to_target++;
	s->ops->to_target(s->ctx, d);
}

/* Has the target (or router) seen anything it would wait on? */
static bool target_engaged(const gw_sdo_route *s)
{
	return s->frames_to_target > 0;
}

/* End the session with aborts: `req` to the requester, `tgt` to the
 * target if it is engaged (0 = none). */
static int fail(gw_sdo_route *s, uint32_t req, uint32_t tgt, gw_route_outcome o)
{
	uint8_t d[8];

	if (tgt && target_engaged(s)) {
		gw_sdo_abort_encode(d, s->mux, tgt);
		to_target(s, d);
	}
	gw_sdo_abort_encode(d, s->mux, req);
	to_requester(s, d);
	s->abort = req;
	s->outcome = (uint8_t)o;
	return GW_SR_DONE;
}

static int protocol_error(gw_sdo_route *s)
{
	return fail(s, SDO_AB_CMD, SDO_AB_CMD, GW_OUT_ABORTED);
}

static int finish_ok(gw_sdo_route *s)
{
	s->abort = 0;
	s->outcome = GW_OUT_ROUTED;
	return GW_SR_DONE;
}

/* An abort passes through to the other side and ends the session. */
static int relay_abort(gw_sdo_route *s, const uint8_t d[8], bool from_requester)
{
	if (from_requester) {
		if (target_engaged(s))
			to_target(s, d);
	} else {
		to_requester(s, d);
	}
	s->abort = co_get_le32(&d[4]);
	s->outcome = GW_OUT_ABORTED;
	return GW_SR_DONE;
}

static bool is_abort(const uint8_t d[8], bool in_sub_block)
{
	return in_sub_block ? d[0] == 0x80 : CS(d) == SDO_CCS_ABORT;
}

/* ---- states ------------------------------------------------------------------- */

static int opening_enter(void *obj, uint64_t now_us);
static int hop_enter(void *obj, uint64_t now_us);
static int hop_con(void *obj, const void *con, uint64_t now_us);
static int wait_init_enter(void *obj, uint64_t now_us);
static int done_enter(void *obj, uint64_t now_us);
static int on_timeout(void *obj, uint64_t now_us);

/* Every transfer state has one handler for the side whose turn it is and
 * one for the other side, which may only abort (or breaks the protocol).
 * The handlers are made by REQUESTER_TURN/TARGET_TURN below from a step
 * that sees the frame once the abort and the lost target are dealt with. */
static int requester_out_of_turn(void *obj, const co_frame *f, uint64_t now_us);
static int target_out_of_turn(void *obj, const void *con, uint64_t now_us);
#define STEP_DECL(step)                                                             \
	static int step##_requester(void *obj, const co_frame *f, uint64_t now_us); \
	static int step##_target(void *obj, const void *con, uint64_t now_us)
STEP_DECL(wait_init);
STEP_DECL(dn_init_resp);
STEP_DECL(dn_seg_req);
STEP_DECL(dn_seg_resp);
STEP_DECL(up_init_resp);
STEP_DECL(up_seg_req);
STEP_DECL(up_seg_resp);
STEP_DECL(blk_dn_init_resp);
STEP_DECL(blk_dn_sub);
STEP_DECL(blk_dn_end_req);
STEP_DECL(blk_dn_end_resp);
STEP_DECL(blk_up_init_resp);
STEP_DECL(blk_up_start);
STEP_DECL(blk_up_sub);
STEP_DECL(blk_up_end);
STEP_DECL(blk_up_end_resp);

#define TURN(nm, step)                                                             \
	{                                                                          \
		.name = nm, .on_frame = step##_requester, .on_con = step##_target, \
		.on_timeout = on_timeout                                           \
	}

static const co_fsm_state states[GW_SR_COUNT] = {
	[GW_SR_IDLE] = { .name = "idle" },
	[GW_SR_OPENING] = { .name = "opening", .on_enter = opening_enter },
	[GW_SR_HOP] = { .name = "next router",
			.on_enter = hop_enter,
			.on_frame = requester_out_of_turn,
			.on_con = hop_con,
			.on_timeout = on_timeout },
	[GW_SR_WAIT_INIT] = { .name = "wait initiate",
			      .on_enter = wait_init_enter,
			      .on_frame = wait_init_requester,
			      .on_con = wait_init_target,
			      .on_timeout = on_timeout },
	[GW_SR_DN_INIT_RESP] = TURN("download initiate", dn_init_resp),
	[GW_SR_DN_SEG_REQ] = TURN("download segment request", dn_seg_req),
	[GW_SR_DN_SEG_RESP] = TURN("download segment response", dn_seg_resp),
	[GW_SR_UP_INIT_RESP] = TURN("upload initiate", up_init_resp),
	[GW_SR_UP_SEG_REQ] = TURN("upload segment request", up_seg_req),
	[GW_SR_UP_SEG_RESP] = TURN("upload segment response", up_seg_resp),
	[GW_SR_BLK_DN_INIT_RESP] = TURN("block download initiate", blk_dn_init_resp),
	[GW_SR_BLK_DN_SUB] = TURN("block download sub-block", blk_dn_sub),
	[GW_SR_BLK_DN_END_REQ] = TURN("block download end request", blk_dn_end_req),
	[GW_SR_BLK_DN_END_RESP] = TURN("block download end response", blk_dn_end_resp),
	[GW_SR_BLK_UP_INIT_RESP] = TURN("block upload initiate", blk_up_init_resp),
	[GW_SR_BLK_UP_START] = TURN("block upload start", blk_up_start),
	[GW_SR_BLK_UP_SUB] = TURN("block upload sub-block", blk_up_sub),
	[GW_SR_BLK_UP_END] = TURN("block upload end", blk_up_end),
	[GW_SR_BLK_UP_END_RESP] = TURN("block upload end response", blk_up_end_resp),
	[GW_SR_DONE] = { .name = "done", .on_enter = done_enter },
};

static const co_fsm_def route_fsm = { "sdo_route", states, GW_SR_COUNT };

const char *gw_sdo_route_state_to_string(gw_sdo_route_state st)
{
	return co_fsm_state_name(&route_fsm, (int)st);
}

/* OPENING: refuse at once, or take the lease (decided by ops->open without
 * a round trip to the target line, docs/gateway.md) and go on. */
static int opening_enter(void *obj, uint64_t now_us)
{
	gw_sdo_route *s = obj;
	uint32_t ab = s->refuse;

	(void)now_us;
	if (!ab)
		ab = s->ops->open(s->ctx, &s->hop);
	if (ab)
		return fail(s, ab, 0, GW_OUT_REFUSED);
	s->opened = true;
	return s->hop.via_router ? GW_SR_HOP : GW_SR_WAIT_INIT;
}

/* HOP: the same indication goes to the next router first. */
static int hop_enter(void *obj, uint64_t now_us)
{
	gw_sdo_route *s = obj;
	uint8_t d[8];

	(void)now_us;
	gw_netind_encode(d, s->target);
	to_target(s, d);
	return CO_FSM_STAY;
}

static int hop_con(void *obj, const void *con, uint64_t now_us)
{
	gw_sdo_route *s = obj;
	const gw_sdo_route_con *c = con;
	const uint8_t *d = c->data;

	(void)now_us;
	if (c->kind == GW_CON_LOST)
		return fail(s, c->abort ? c->abort : GW_AB_NO_ANSWER, 0, GW_OUT_ABORTED);
	if (c->kind != GW_CON_TARGET_FRAME)
		return CO_FSM_STAY;
	if (CS(d) == SDO_CCS_ABORT) {
		/* The router refused: its abort names the same network/node. */
		to_requester(s, d);
		s->abort = co_get_le32(&d[4]);
		s->outcome = GW_OUT_REFUSED;
		return GW_SR_DONE;
	}
	if (d[0] != GW_NETIND_CS || memcmp(&d[1], s->mux, 3) != 0)
		return protocol_error(s);
	s->target_answered = true;
	return GW_SR_WAIT_INIT;
}

static int wait_init_enter(void *obj, uint64_t now_us)
{
	gw_sdo_route *s = obj;
	uint8_t d[8];

	(void)now_us;
	gw_netind_encode(d, s->target);
	to_requester(s, d);
	s->confirmed = true;
	return CO_FSM_STAY;
}

static int done_enter(void *obj, uint64_t now_us)
{
	gw_sdo_route *s = obj;

	(void)now_us;
	if (s->opened) {
		s->opened = false;
		s->ops->close(s->ctx);
	}
	s->deadline_us = UINT64_MAX;
	s->ops->done(s->ctx, s->abort, (gw_route_outcome)s->outcome);
	return GW_SR_IDLE;
}

static int on_timeout(void *obj, uint64_t now_us)
{
	gw_sdo_route *s = obj;
	int st = co_fsm_state_of(&s->fsm);

	(void)now_us;
	if (waits_for[st] == SIDE_REQUESTER)
		return fail(s, SDO_AB_TIMEOUT, SDO_AB_TIMEOUT, GW_OUT_TIMED_OUT);
	return fail(s, s->target_answered ? SDO_AB_TIMEOUT : GW_AB_NO_ANSWER, SDO_AB_TIMEOUT,
		    GW_OUT_TIMED_OUT);
}

/* ---- requester frames --------------------------------------------------------- */

static int req_wait_init(gw_sdo_route *s, const uint8_t *d)
{
	int next;

	switch (CS(d)) {
	case SDO_CCS_DN_INIT:
		s->expedited = d[0] & SDO_EXPEDITED;
		next = GW_SR_DN_INIT_RESP;
		break;
	case SDO_CCS_UP_INIT:
		next = GW_SR_UP_INIT_RESP;
		break;
	case SDO_CCS_BLK_DN:
		if (d[0] & 1u)
			return protocol_error(s);
		next = GW_SR_BLK_DN_INIT_RESP;
		break;
	case SDO_CCS_BLK_UP:
		if (d[0] & 3u)
			return protocol_error(s);
		next = GW_SR_BLK_UP_INIT_RESP;
		break;
	default:
		return protocol_error(s);
	}
	memcpy(s->mux, &d[1], 3);
	s->started = true;
	s->last = false;
	to_target(s, d);
	return next;
}

/* A segment of a block download sub-block (c bit + sequence number). */
static int req_blk_dn_segment(gw_sdo_route *s, const uint8_t *d)
{
	uint8_t seq = d[0] & 0x7Fu;

	if (seq == 0)
		return protocol_error(s);
	if (d[0] & SDO_BLK_SEQ_LAST) {
		s->last = true;
		s->last_seq = seq;
	}
	to_target(s, d);
	return CO_FSM_STAY;
}

/* The requester's ack of a block upload sub-block. */
static int req_blk_up_ack(gw_sdo_route *s, const uint8_t *d)
{
	if (d[0] != ((SDO_CCS_BLK_UP << 5) | SDO_BLK_ACK))
		return protocol_error(s);
	to_target(s, d);
	if (s->last && d[1] >= s->last_seq)
		return GW_SR_BLK_UP_END;
	s->last = false; /* segments are repeated from ackseq + 1 */
	return CO_FSM_STAY;
}

/* Forward d if byte 0 matches (mask, value); go to next. */
static int req_expect(gw_sdo_route *s, const uint8_t *d, uint8_t mask, uint8_t value, int next)
{
	if ((d[0] & mask) != value)
		return protocol_error(s);
	to_target(s, d);
	return next;
}

/* What every requester frame goes through: an abort passes to the target
 * and ends the session (inside a block download sub-block only the exact
 * abort byte is one; other bytes there are segment numbers). */
static int requester_turn(void *obj, const co_frame *f, bool sub_block,
			  int (*step)(gw_sdo_route *s, const uint8_t *d))
{
	gw_sdo_route *s = obj;

	if (is_abort(f->data, sub_block))
		return relay_abort(s, f->data, true);
	return step(s, f->data);
}

static int not_your_turn(gw_sdo_route *s, const uint8_t *d)
{
	(void)d;
	return protocol_error(s);
}

static int requester_out_of_turn(void *obj, const co_frame *f, uint64_t now_us)
{
	(void)now_us;
	return requester_turn(obj, f, false, not_your_turn);
}

static int dn_seg_req(gw_sdo_route *s, const uint8_t *d)
{
	if (CS(d) == SDO_CCS_DN_SEG)
		s->last = d[0] & SDO_SEG_LAST;
	return req_expect(s, d, 0xE0, SDO_CCS_DN_SEG << 5, GW_SR_DN_SEG_RESP);
}

static int up_seg_req(gw_sdo_route *s, const uint8_t *d)
{
	return req_expect(s, d, 0xE0, SDO_CCS_UP_SEG << 5, GW_SR_UP_SEG_RESP);
}

static int blk_dn_end_req(gw_sdo_route *s, const uint8_t *d)
{
	return req_expect(s, d, 0xE3, (SDO_CCS_BLK_DN << 5) | SDO_BLK_END, GW_SR_BLK_DN_END_RESP);
}

static int blk_up_start(gw_sdo_route *s, const uint8_t *d)
{
	return req_expect(s, d, 0xFF, (SDO_CCS_BLK_UP << 5) | SDO_BLK_START, GW_SR_BLK_UP_SUB);
}

static int blk_up_end_resp(gw_sdo_route *s, const uint8_t *d)
{
	if (d[0] != ((SDO_CCS_BLK_UP << 5) | SDO_BLK_END))
		return protocol_error(s);
	to_target(s, d);
	return finish_ok(s);
}

/* ---- target frames ------------------------------------------------------------ */

static int tgt_expect(gw_sdo_route *s, const uint8_t *d, uint8_t mask, uint8_t value, int next)
{
	if ((d[0] & mask) != value)
		return protocol_error(s);
	to_requester(s, d);
	return next;
}

static int tgt_blk_up_init(gw_sdo_route *s, const uint8_t *d)
{
	if (CS(d) == SDO_SCS_UP_INIT) {
		/* The server switched to a normal upload (size <= threshold). */
		to_requester(s, d);
		return (d[0] & SDO_EXPEDITED) ? finish_ok(s) : GW_SR_UP_SEG_REQ;
	}
	return tgt_expect(s, d, 0xE1, SDO_SCS_BLK_UP << 5, GW_SR_BLK_UP_START);
}

static int tgt_blk_dn_ack(gw_sdo_route *s, const uint8_t *d)
{
	if (d[0] != ((SDO_SCS_BLK_DN << 5) | SDO_BLK_ACK))
		return protocol_error(s);
	to_requester(s, d);
	if (s->last && d[1] >= s->last_seq)
		return GW_SR_BLK_DN_END_REQ;
	s->last = false;
	return CO_FSM_STAY;
}

static int tgt_blk_up_segment(gw_sdo_route *s, const uint8_t *d)
{
	uint8_t seq = d[0] & 0x7Fu;

	if (seq == 0)
		return protocol_error(s);
	if (d[0] & SDO_BLK_SEQ_LAST) {
		s->last = true;
		s->last_seq = seq;
	}
	to_requester(s, d);
	return CO_FSM_STAY;
}

/* What every answer of the target line goes through: the target lost
 * (lease ended, link down) ends the session; an abort passes to the
 * requester (inside a block upload sub-block only the exact abort byte is
 * one); any other frame shows the target answered, then the step sees it. */
static int target_turn(void *obj, const void *con, bool sub_block,
		       int (*step)(gw_sdo_route *s, const uint8_t *d))
{
	gw_sdo_route *s = obj;
	const gw_sdo_route_con *c = con;

	if (c->kind == GW_CON_LOST)
		return fail(s, c->abort ? c->abort : GW_AB_NO_ANSWER, 0, GW_OUT_ABORTED);
	if (c->kind != GW_CON_TARGET_FRAME)
		return CO_FSM_STAY;
	if (is_abort(c->data, sub_block))
		return relay_abort(s, c->data, false);
	s->target_answered = true;
	return step(s, c->data);
}

static int target_out_of_turn(void *obj, const void *con, uint64_t now_us)
{
	(void)now_us;
	return target_turn(obj, con, false, not_your_turn);
}

static int dn_init_resp(gw_sdo_route *s, const uint8_t *d)
{
	if (d[0] != (SDO_SCS_DN_INIT << 5))
		return protocol_error(s);
	to_requester(s, d);
	return s->expedited ? finish_ok(s) : GW_SR_DN_SEG_REQ;
}

static int dn_seg_resp(gw_sdo_route *s, const uint8_t *d)
{
	if ((d[0] & 0xEF) != (SDO_SCS_DN_SEG << 5))
		return protocol_error(s);
	to_requester(s, d);
	return s->last ? finish_ok(s) : GW_SR_DN_SEG_REQ;
}

static int up_init_resp(gw_sdo_route *s, const uint8_t *d)
{
	if (CS(d) != SDO_SCS_UP_INIT)
		return protocol_error(s);
	to_requester(s, d);
	return (d[0] & SDO_EXPEDITED) ? finish_ok(s) : GW_SR_UP_SEG_REQ;
}

static int up_seg_resp(gw_sdo_route *s, const uint8_t *d)
{
	if (CS(d) != SDO_SCS_UP_SEG)
		return protocol_error(s);
	to_requester(s, d);
	return (d[0] & SDO_SEG_LAST) ? finish_ok(s) : GW_SR_UP_SEG_REQ;
}

static int blk_dn_init_resp(gw_sdo_route *s, const uint8_t *d)
{
	return tgt_expect(s, d, 0xE3, SDO_SCS_BLK_DN << 5, GW_SR_BLK_DN_SUB);
}

static int blk_dn_end_resp(gw_sdo_route *s, const uint8_t *d)
{
	if (d[0] != ((SDO_SCS_BLK_DN << 5) | SDO_BLK_END))
		return protocol_error(s);
	to_requester(s, d);
	return finish_ok(s);
}

static int blk_up_end(gw_sdo_route *s, const uint8_t *d)
{
	return tgt_expect(s, d, 0xE3, (SDO_SCS_BLK_UP << 5) | SDO_BLK_END, GW_SR_BLK_UP_END_RESP);
}

/* ---- the handlers of each state: whose turn, which step ----------------------- */

#define REQUESTER_TURN(state, step, sub_block)                                      \
	static int state##_requester(void *obj, const co_frame *f, uint64_t now_us) \
	{                                                                           \
		(void)now_us;                                                       \
		return requester_turn(obj, f, sub_block, step);                     \
	}                                                                           \
	static int state##_target(void *obj, const void *con, uint64_t now_us)      \
	{                                                                           \
		return target_out_of_turn(obj, con, now_us);                        \
	}
#define TARGET_TURN(state, step, sub_block)                                         \
	static int state##_requester(void *obj, const co_frame *f, uint64_t now_us) \
	{                                                                           \
		return requester_out_of_turn(obj, f, now_us);                       \
	}                                                                           \
	static int state##_target(void *obj, const void *con, uint64_t now_us)      \
	{                                                                           \
		(void)now_us;                                                       \
		return target_turn(obj, con, sub_block, step);                      \
	}

/* WAIT_INIT: confirmed, and nothing of the transfer reached the target.
 * The requester's next frame is the transfer the confirmation announced:
 * it is the session's whatever happened meanwhile - if the lease ended
 * (the target line could not bind it, or lost its link), that initiate is
 * answered with the reason, carrying its own multiplexer; an abort sent
 * before it would not be the transfer's (CiA 301 §7.2.4.3.17: an abort
 * names the transfer's index and sub-index), and the initiate would then
 * reach the gateway's own SDO server, which would answer it as a request
 * for its own dictionary. */
static int wait_init_requester(void *obj, const co_frame *f, uint64_t now_us)
{
	gw_sdo_route *s = obj;

	(void)now_us;
	if (!s->lost || is_abort(f->data, false))
		return requester_turn(obj, f, false, req_wait_init);
	memcpy(s->mux, &f->data[1], 3);
	return fail(s, s->lost, 0, GW_OUT_ABORTED);
}

/* Before the initiate the target has nothing of this transfer: a frame
 * from it answers another client of the same server channel (the
 * transfer it ends, or one it aborts) and is not the session's. */
static int wait_init_target(void *obj, const void *con, uint64_t now_us)
{
	gw_sdo_route *s = obj;
	const gw_sdo_route_con *c = con;

	(void)now_us;
	if (c->kind == GW_CON_LOST && !s->lost)
		s->lost = c->abort ? c->abort : GW_AB_NO_ANSWER;
	return CO_FSM_STAY;
}

TARGET_TURN(dn_init_resp, dn_init_resp, false)
REQUESTER_TURN(dn_seg_req, dn_seg_req, false)
TARGET_TURN(dn_seg_resp, dn_seg_resp, false)
TARGET_TURN(up_init_resp, up_init_resp, false)
REQUESTER_TURN(up_seg_req, up_seg_req, false)
TARGET_TURN(up_seg_resp, up_seg_resp, false)
TARGET_TURN(blk_dn_init_resp, blk_dn_init_resp, false)
REQUESTER_TURN(blk_dn_end_req, blk_dn_end_req, false)
TARGET_TURN(blk_dn_end_resp, blk_dn_end_resp, false)
TARGET_TURN(blk_up_init_resp, tgt_blk_up_init, false)
REQUESTER_TURN(blk_up_start, blk_up_start, false)
TARGET_TURN(blk_up_end, blk_up_end, false)
REQUESTER_TURN(blk_up_end_resp, blk_up_end_resp, false)

/* The two sub-block states: both sides speak (segments one way, the ack
 * the other), and the side sending segments aborts only with the exact
 * abort byte. */
static int blk_dn_sub_requester(void *obj, const co_frame *f, uint64_t now_us)
{
	(void)now_us;
	return requester_turn(obj, f, true, req_blk_dn_segment);
}

static int blk_dn_sub_target(void *obj, const void *con, uint64_t now_us)
{
	(void)now_us;
	return target_turn(obj, con, false, tgt_blk_dn_ack);
}

static int blk_up_sub_requester(void *obj, const co_frame *f, uint64_t now_us)
{
	(void)now_us;
	return requester_turn(obj, f, false, req_blk_up_ack);
}

static int blk_up_sub_target(void *obj, const void *con, uint64_t now_us)
{
	(void)now_us;
	return target_turn(obj, con, true, tgt_blk_up_segment);
}

/* ---- API ------------------------------------------------------------------------ */

/* The same checks as dn_init_resp, dn_seg_resp, up_init_resp and
 * up_seg_resp; an abort passes in each of those states (target_turn). */
bool gw_sdo_route_answer_passes(uint8_t asked, const uint8_t answer[8])
{
	if (CS(answer) == SDO_SCS_ABORT)
		return CS(&asked) <= SDO_CCS_UP_SEG;
	switch (CS(&asked)) {
	case SDO_CCS_DN_INIT:
		return answer[0] == (SDO_SCS_DN_INIT << 5);
	case SDO_CCS_DN_SEG:
		return (answer[0] & 0xEF) == (SDO_SCS_DN_SEG << 5);
	case SDO_CCS_UP_INIT:
		return CS(answer) == SDO_SCS_UP_INIT;
	case SDO_CCS_UP_SEG:
		return CS(answer) == SDO_SCS_UP_SEG;
	default:
		return false;
	}
}

static void rearm(gw_sdo_route *s, uint64_t now_us)
{
	int st = co_fsm_state_of(&s->fsm);
	uint32_t ms;

	if (st == GW_SR_IDLE) {
		s->deadline_us = UINT64_MAX;
		return;
	}
	switch (waits_for[st]) {
	case SIDE_REQUESTER:
		ms = s->requester_timeout_ms;
		break;
	case SIDE_TARGET:
		ms = s->target_timeout_ms;
		break;
	default:
		ms = s->requester_timeout_ms > s->target_timeout_ms ? s->requester_timeout_ms
								    : s->target_timeout_ms;
		break;
	}
	s->deadline_us = now_us + (uint64_t)ms * 1000u;
}

void gw_sdo_route_init(gw_sdo_route *s, const gw_sdo_route_ops *ops, void *ctx)
{
	memset(s, 0, sizeof(*s));
	s->ops = ops;
	s->ctx = ctx;
	s->deadline_us = UINT64_MAX;
	co_fsm_init(&s->fsm, &route_fsm, s, GW_SR_IDLE);
}

int gw_sdo_route_start(gw_sdo_route *s, gw_netind ni, uint32_t refuse, const gw_hop *hop,
		       uint32_t requester_timeout_ms, uint32_t target_timeout_ms, uint64_t now_us)
{
	if (gw_sdo_route_busy(s))
		return -EBUSY;
	s->target = ni;
	s->hop = hop ? *hop : (gw_hop){ 0 };
	s->requester_timeout_ms = requester_timeout_ms ? requester_timeout_ms : 1000;
	s->target_timeout_ms = target_timeout_ms ? target_timeout_ms : 1000;
	s->opened = s->confirmed = s->target_answered = s->started = false;
	s->expedited = s->last = false;
	s->abort = 0;
	s->lost = 0;
	s->outcome = GW_OUT_ROUTED;
	s->frames_to_target = s->frames_to_requester = 0;
	co_put_le16(&s->mux[0], ni.net);
	s->mux[2] = ni.node;
	s->refuse = refuse;
	s->now_us = now_us;
	/* A refusal, too, leaves through DONE: one done() per session. */
	co_fsm_goto(&s->fsm, GW_SR_OPENING, now_us);
	rearm(s, now_us);
	return 0;
}

void gw_sdo_route_requester_frame(gw_sdo_route *s, const uint8_t d[8], uint64_t now_us)
{
	co_frame f;

	if (!gw_sdo_route_busy(s))
		return;
	co_frame_init(&f, 0, 8);
	memcpy(f.data, d, 8);
	s->now_us = now_us;
	co_fsm_frame(&s->fsm, &f, now_us);
	rearm(s, now_us);
}

static void deliver(gw_sdo_route *s, const gw_sdo_route_con *c, uint64_t now_us)
{
	if (!gw_sdo_route_busy(s))
		return;
	s->now_us = now_us;
	co_fsm_con(&s->fsm, c, now_us);
	rearm(s, now_us);
}

void gw_sdo_route_target_frame(gw_sdo_route *s, const uint8_t d[8], uint64_t now_us)
{
	gw_sdo_route_con c = { .kind = GW_CON_TARGET_FRAME };

	memcpy(c.data, d, 8);
	deliver(s, &c, now_us);
}

void gw_sdo_route_lost(gw_sdo_route *s, uint32_t abort, uint64_t now_us)
{
	gw_sdo_route_con c = { .kind = GW_CON_LOST, .abort = abort };

	deliver(s, &c, now_us);
}

void gw_sdo_route_tick(gw_sdo_route *s, uint64_t now_us)
{
	if (!gw_sdo_route_busy(s) || now_us < s->deadline_us)
		return;
	s->now_us = now_us;
	co_fsm_timeout(&s->fsm, now_us);
	rearm(s, now_us);
}

void gw_sdo_route_cancel(gw_sdo_route *s, uint32_t abort, uint64_t now_us)
{
	if (!gw_sdo_route_busy(s))
		return;
	s->now_us = now_us;
	co_fsm_goto(&s->fsm, fail(s, abort, abort, GW_OUT_ABORTED), now_us);
	rearm(s, now_us);
}
