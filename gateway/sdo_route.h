/* SPDX-License-Identifier: MIT */
/*
 * gateway/sdo_route.h - one routed SDO transfer (CiA 302-7 SDO networking),
 * as a state machine in the core/fsm.h shape.
 *
 * A session lives on the line where the request entered, bound to one SDO
 * server channel of that line ("requester" side). After a network
 * indication it opens a lease on the target line (an SDO client channel
 * of the pool there, toward the target node or the next router: ops.open
 * decides at once, from what the target line publishes), confirms
 * the indication (after the next router confirmed it, for a network
 * further away), then relays the one SDO transfer that follows frame by
 * frame in both directions - expedited, segmented or block, upload or
 * download - without buffering the value. It tracks the protocol only as
 * far as needed to know who speaks next and when the transfer ends.
 *
 * Refusals come at once, as aborts in the network indication layout
 * (convention.h): unknown network / loop (the caller resolved the route),
 * target line down, node known silent, node busy, no free client, a full
 * hand-off ring (all from ops.open). A lease lost later (the target line
 * could not bind it, or lost its link) ends the transfer with that abort
 * (gw_sdo_route_lost). Timeouts are per frame, as for any SDO
 * transfer: a target that never answered gives GW_AB_NO_ANSWER, one that
 * went silent mid-transfer 05040000; a silent requester gets 05040000 and
 * the target an abort, so both ends are released.
 *
 * Pure logic: frames and time in, actions out through the ops; the owner
 * keeps the timer (gw_sdo_route_deadline) and the threads.
 */
#ifndef COGW_GATEWAY_SDO_ROUTE_H
#define COGW_GATEWAY_SDO_ROUTE_H

#include <stdbool.h>
#include <stdint.h>

#include "core/fsm.h"
#include "gateway/convention.h"
#include "gateway/route.h"

typedef enum gw_sdo_route_state {
	GW_SR_IDLE,
	GW_SR_OPENING,          /* lease taken or refused (passes at once) */
	GW_SR_HOP,              /* network indication sent to the next router */
	GW_SR_WAIT_INIT,        /* confirmed; waiting for the requester's initiate */
	GW_SR_DN_INIT_RESP,     /* download initiate relayed */
	GW_SR_DN_SEG_REQ,       /* waiting for the requester's next segment */
	GW_SR_DN_SEG_RESP,      /* segment relayed, waiting for its response */
	GW_SR_UP_INIT_RESP,     /* upload initiate relayed */
	GW_SR_UP_SEG_REQ,       /* waiting for the requester's segment request */
	GW_SR_UP_SEG_RESP,      /* segment request relayed */
	GW_SR_BLK_DN_INIT_RESP, /* block download initiate relayed */
	GW_SR_BLK_DN_SUB,       /* sub-block segments flow to the target */
	GW_SR_BLK_DN_END_REQ,   /* last segment acknowledged: requester's end */
	GW_SR_BLK_DN_END_RESP,  /* end relayed */
	GW_SR_BLK_UP_INIT_RESP, /* block upload initiate relayed */
	GW_SR_BLK_UP_START,     /* waiting for the requester's "start" */
	GW_SR_BLK_UP_SUB,       /* sub-block segments flow to the requester */
	GW_SR_BLK_UP_END,       /* last segment acknowledged: target's end */
	GW_SR_BLK_UP_END_RESP,  /* end relayed, waiting for its response */
	GW_SR_DONE,             /* release everything, report, back to idle */
	GW_SR_COUNT
} gw_sdo_route_state;

const char *gw_sdo_route_state_to_string(gw_sdo_route_state s);

typedef struct gw_sdo_route_ops {
	/* Send 8 bytes to the requester (on the server channel's COB-ID). */
	void (*to_requester)(void *ctx, const uint8_t d[8]);
	/* Relay 8 bytes to the target (or next router) on the target line. */
	void (*to_target)(void *ctx, const uint8_t d[8]);
	/* Take a lease on the target line toward hop->node. Return 0 (the
	 * lease is the session's: close() owed), or an abort code to refuse
	 * at once. A lease that is lost later comes as gw_sdo_route_lost(). */
	uint32_t (*open)(void *ctx, const gw_hop *hop);
	/* Give the lease back (only called after open returned 0). */
	void (*close)(void *ctx);
	/* The session ended: abort 0 = the transfer completed; the server
	 * channel may be given back. Called exactly once per started session. */
	void (*done)(void *ctx, uint32_t abort, gw_route_outcome outcome);
} gw_sdo_route_ops;

typedef struct gw_sdo_route {
	co_fsm fsm;
	const gw_sdo_route_ops *ops;
	void *ctx;

	gw_netind target; /* what the requester asked for */
	gw_hop hop;       /* where it goes */
	uint32_t requester_timeout_ms;
	uint32_t target_timeout_ms;
	uint64_t deadline_us; /* UINT64_MAX = none */
	uint64_t now_us;

	bool opened;          /* open() returned 0: close() owed */
	bool confirmed;       /* the indication was confirmed to the requester */
	bool target_answered; /* the target sent anything for the transfer */
	bool started;         /* an initiate was relayed to the target */
	uint8_t mux[3];       /* index/sub of the transfer (for our aborts) */
	bool expedited;       /* download initiate carried the data */
	bool last;            /* the last segment went through */
	uint8_t last_seq;     /* its sequence number (block) */
	uint32_t refuse;      /* refusal given to start() */
	uint32_t lost;        /* the lease ended before the initiate: its abort */
	uint32_t abort;       /* outcome code */
	uint8_t outcome;      /* gw_route_outcome */
	uint64_t frames_to_target, frames_to_requester;
} gw_sdo_route;

/* Input delivered through co_fsm_con (target side). */
typedef enum gw_sdo_route_con_kind {
	GW_CON_TARGET_FRAME = 1, /* a frame from the target (or next router) */
	GW_CON_LOST,             /* the target line lost the lease (line down) */
} gw_sdo_route_con_kind;

typedef struct gw_sdo_route_con {
	uint8_t kind;
	uint32_t abort;
	uint8_t data[8];
} gw_sdo_route_con;

void gw_sdo_route_init(gw_sdo_route *s, const gw_sdo_route_ops *ops, void *ctx);

/* A network indication arrived (decoded into ni). refuse != 0: answer it
 * with that abort at once (caller's route lookup or decode said so; hop
 * is ignored). Otherwise the session opens the lease toward hop and
 * confirms (or sends the indication to the next router) in this call.
 * -EBUSY if the session is not idle. */
int gw_sdo_route_start(gw_sdo_route *s, gw_netind ni, uint32_t refuse, const gw_hop *hop,
		       uint32_t requester_timeout_ms, uint32_t target_timeout_ms, uint64_t now_us);

/* A frame from the requester (8 bytes of the server channel). */
void gw_sdo_route_requester_frame(gw_sdo_route *s, const uint8_t d[8], uint64_t now_us);
/* A frame from the target side. */
void gw_sdo_route_target_frame(gw_sdo_route *s, const uint8_t d[8], uint64_t now_us);
/* The target line lost the lease (line down, bus-off, or it could not
 * bind it). */
void gw_sdo_route_lost(gw_sdo_route *s, uint32_t abort, uint64_t now_us);
/* Run the timer (a no-op before the deadline). */
void gw_sdo_route_tick(gw_sdo_route *s, uint64_t now_us);
/* End the session now (server channel reset, shutdown): aborts to both
 * sides with `abort`, outcome ABORTED. No-op when idle. */
void gw_sdo_route_cancel(gw_sdo_route *s, uint32_t abort, uint64_t now_us);

/* Would the session forward the target's frame `answer` unchanged as the
 * one answer to the requester's frame that began with `asked`, in a
 * normal (not block) transfer? What a lease may send to the requester
 * itself (docs/gateway.md, frames across interfaces). */
bool gw_sdo_route_answer_passes(uint8_t asked, const uint8_t answer[8]);

static inline bool gw_sdo_route_busy(const gw_sdo_route *s)
{
	return co_fsm_state_of(&s->fsm) != GW_SR_IDLE;
}
static inline uint64_t gw_sdo_route_deadline(const gw_sdo_route *s)
{
	return s->deadline_us;
}
static inline gw_sdo_route_state gw_sdo_route_state_of(const gw_sdo_route *s)
{
	return (gw_sdo_route_state)co_fsm_state_of(&s->fsm);
}

#endif /* COGW_GATEWAY_SDO_ROUTE_H */
