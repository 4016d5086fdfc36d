/* SPDX-License-Identifier: MIT */
/*
 * core/sdo_client.h - SDO client channels (CiA 301 §7.2.4, objects
 * 1280h..12FFh) for a manager and a gateway.
 *
 * - cfg.sdo_client_count channels; 1280h+n is created in the OD if absent
 *   and reflects the current target (sub 1/2 COB-IDs, sub 3 node-ID).
 * - Each channel has a FIFO of cfg.sdo_client_queue_len requests, fixed at
 *   node creation: submitting never allocates, and callers see -ENOSPC only
 *   when that bound is reached, never "busy".
 * - The target node is set per request; the channel's COB-IDs follow it
 *   (600h+node / 580h+node unless the request overrides them). Two channels
 *   never talk to the same server COB-ID at once: a request whose target is
 *   in use by another channel waits in its queue.
 * - Modes: expedited (1..4 bytes), segmented, block (with CRC). AUTO picks
 *   expedited for 1..4 bytes, block at >= cfg.sdo_client_block_threshold,
 *   else segmented. When a server refuses a block initiate with 0x05040001
 *   or 0x06010000 the request is repeated segmented (event.mode tells).
 *   Uploads use block only when asked (mode BLOCK) or when the request's
 *   expected size (size field) reaches the threshold; the client then
 *   offers the threshold (<= 255) as protocol switch threshold.
 * - Timeout: timeout_ms per frame, restarted on every frame received for
 *   the transfer (CiA leaves the value to the application). A request
 *   waiting in the queue has no timeout yet; cancel it if it waits too long.
 * - Data: a buffer, or chunk callbacks for domains of any size (the client
 *   keeps only one sub-block, 889 bytes, per channel).
 * - Completion: exactly one CO_EV_SDO_CLIENT_DONE per accepted request,
 *   carrying the caller's tag, the abort code (0 = success) and the size,
 *   and, if the request names one, exactly one call of its confirmation
 *   `con(con_arg, &event)` just before that event. Both come on the owning
 *   thread and never from inside the submitting call (a request that
 *   cannot even start, e.g. no receiver left for its COB-ID, is reported
 *   from the next co_node_tick(); the node's deadline says when).
 *
 * Two ways to get a channel:
 * - The pool (sdo_client_pool_submit): the request borrows any free
 *   channel (idle, with nothing queued on it) and returns it at
 *   completion. A busy channel never holds back a request another channel
 *   could serve. Requests that find no free channel, or whose target is
 *   busy on some channel (one transfer per server channel, CiA 301), wait
 *   in one bounded FIFO of cfg.sdo_client_pool_len entries; they start in
 *   order as channels and targets free up, so two requests to the same
 *   node run one after the other in submission order. -ENOSPC when that
 *   FIFO is full. With req.no_wait the request is refused at once with
 *   -EBUSY instead of waiting (the caller reports SDO_AB_NO_RESOURCE,
 *   0x060A0023, "resource not available: SDO connection").
 * - A named channel (sdo_client_submit): the request waits in that
 *   channel's own FIFO (tests, tools that need a fixed 1280h+n).
 * A channel with requests in its own FIFO is not free for the pool.
 *
 * - Own NMT state STOPPED (CiA 301 §7.3.2.2: no SDO there): a running
 *   transfer ends without a frame, and every request that would start
 *   completes from the next tick instead; all with 0x08000022 (device
 *   state).
 * - An answer that names another object than the request aborts the
 *   transfer at once with 0x06040043 (general parameter incompatibility).
 *   Exception: after a channel ended a transfer with its own abort frame
 *   (cancel, timeout, protocol error), late frames of that transfer (its
 *   segments, its answer naming the old object) are ignored by the next
 *   transfer to the same server until that one's first answer arrives.
 */
#ifndef COGW_CORE_SDO_CLIENT_H
#define COGW_CORE_SDO_CLIENT_H

#include <stdbool.h>
#include <stdint.h>

#include "core/co.h"
#include "core/sdo.h"

extern const co_service co_svc_sdo_client;

/* Channel number in a completion event of a request cancelled while it
 * still waited in the pool (it never had a channel). */
#define SDO_CLIENT_NO_CHANNEL 0xFFu

/* Per-request confirmation: called once with the request's completion (the
 * same content as the CO_EV_SDO_CLIENT_DONE that follows; con->data is the
 * request's own upload buffer). It may submit or cancel requests. */
typedef void (*sdo_client_con_fn)(void *arg, const co_ev_sdo_cli *con);

/* Download source: copy up to len bytes of the value at offset into buf.
 * Offsets are strictly sequential. Return the count copied (len unless the
 * value ends), or a negative errno to abort (0x08000020 on the wire). */
typedef int (*sdo_src_fn)(void *ctx, uint32_t offset, uint8_t *buf, uint32_t len);
/* Upload sink: the next len bytes at offset (sequential, each byte once).
 * total is the size indicated by the server, or UINT32_MAX if none. Return
 * 0, or a negative errno to abort (on the wire: sdo_abort_of_errno(), e.g.
 * -ENOMEM 0x05040005, any other failure 0x08000020). */
typedef int (*sdo_sink_fn)(void *ctx, uint32_t offset, const uint8_t *data, uint32_t len,
			   uint32_t total);
/* Relayed transfer: where a frame of the request goes instead of the bus
 * (see relay in sdo_client_req). Called on the owning thread, from inside
 * the client: it must not call back into it (submit, cancel, receive). */
typedef void (*sdo_client_relay_fn)(void *ctx, const uint8_t d[8]);

typedef struct sdo_client_req {
	bool upload;     /* true = read from the server, false = write */
	uint8_t node_id; /* target node 1..127 */
	uint16_t index;
	uint8_t sub;
	uint8_t mode;        /* sdo_mode hint */
	uint32_t timeout_ms; /* per frame; 0 = cfg.sdo_client_timeout_ms */
	uint64_t tag;        /* echoed in the completion event */
	uint32_t cob_req;    /* client->server COB-ID; 0 = 600h + node_id */
	uint32_t cob_resp;   /* server->client COB-ID; 0 = 580h + node_id */

	/* Download: size bytes from data, or from src if data is NULL.
	 * Upload: optional expected size (selects block in AUTO mode). */
	uint32_t size;
	const uint8_t *data;
	sdo_src_fn src;

	/* Upload: into buf (cap bytes; more gives 0x05040005), or into sink
	 * if buf is NULL. The buffer must live until the completion event. */
	uint8_t *buf;
	uint32_t cap;
	sdo_sink_fn sink;

	void *ctx; /* for src/sink */

	/* Completion: called once, before the event (NULL = event only). */
	sdo_client_con_fn con;
	void *con_arg;
	/* Pool only: refuse with -EBUSY instead of waiting for a channel. */
	bool no_wait;
	/* Relayed (CiA 302-7 routing, gateway/): the server is on another
	 * network. The transfer runs here as any other, but its frames go to
	 * relay(relay_ctx, d) instead of this node's bus and its answers come
	 * in through sdo_client_relay_recv(). relay_target names that server
	 * (e.g. network << 8 | node) for the rule "one transfer per server at
	 * a time"; it never equals a COB-ID of this bus. 1280h is left alone. */
	sdo_client_relay_fn relay;
	void *relay_ctx;
	uint32_t relay_target;
} sdo_client_req;

/* Queue a request on a channel (0-based); it starts at once if the
 * channel is idle. The request is copied; data/buf it points to must stay
 * valid until completion. Returns 0, -EINVAL (bad request/channel),
 * -ENOSPC (queue full). */
int sdo_client_submit(co_node *node, uint8_t channel, const sdo_client_req *req, uint64_t now_us);

/* Convenience wrappers (AUTO mode). */
int sdo_client_read(co_node *node, uint8_t channel, uint8_t node_id, uint16_t index, uint8_t sub,
		    uint8_t *buf, uint32_t cap, uint32_t timeout_ms, uint64_t tag, uint64_t now_us);
int sdo_client_write(co_node *node, uint8_t channel, uint8_t node_id, uint16_t index, uint8_t sub,
		     const uint8_t *data, uint32_t size, uint32_t timeout_ms, uint64_t tag,
		     uint64_t now_us);

/* Cancel the request with this tag (running: an abort frame with `abort`
 * goes out; queued: removed). Its completion event carries `abort`.
 * Returns 0 or -ENOENT. */
int sdo_client_cancel(co_node *node, uint8_t channel, uint64_t tag, uint32_t abort,
		      uint64_t now_us);

/* Borrow any free channel (see the pool, above). Returns 0, -EINVAL (bad
 * request, no client channels), -EBUSY (no_wait and it cannot start at
 * once), -ENOSPC (pool FIFO full). */
int sdo_client_pool_submit(co_node *node, const sdo_client_req *req, uint64_t now_us);

/* Cancel the request with this tag wherever it is: running on a channel
 * (abort frame with `abort`), waiting in a channel's FIFO or in the pool
 * (removed). Its completion carries `abort`. If several requests share the
 * tag, the first found (running, then channel FIFOs, then pool). Returns 0
 * or -ENOENT. */
int sdo_client_cancel_tag(co_node *node, uint64_t tag, uint32_t abort, uint64_t now_us);

/*
 * Relay lease (CiA 302-7 SDO routing, used by gateway/): borrow a free
 * channel of the pool for raw frames toward one server. Frames given to
 * sdo_client_lease_send() go out unchanged on the request COB-ID
 * (cob_req, 0 = 600h + node_id); every 8-byte frame received on the
 * response COB-ID (cob_resp, 0 = 580h + node_id) goes to fn, until
 * sdo_client_lease_end(). The lease counts as a transfer with that server
 * (pool requests to it wait) and has no timeout: the relay keeps its own.
 * Returns the channel (>= 0), -EBUSY (no free channel), -EALREADY (that
 * server is in a transfer on another channel, or a channel ended one with
 * it by its own abort frame less than 100 ms ago: the server's late frames
 * of that transfer would reach the relay as answers), -ENOSPC (no receiver
 * for the COB-ID), -EINVAL; sdo_abort_of_errno() gives the abort to answer.
 */
typedef void (*sdo_client_raw_fn)(void *arg, const uint8_t d[8], uint64_t now_us);
int sdo_client_lease(co_node *node, uint8_t node_id, uint32_t cob_req, uint32_t cob_resp,
		     sdo_client_raw_fn fn, void *arg, uint64_t now_us);
/*
 * A second user of the pool (CiA 302-7 routing, gateway/; docs/gateway.md
 * "Leases without a round trip"): other threads lend this node's free
 * channels and reserve servers (by node-ID) for relay leases without
 * asking this thread first. With a gate installed the core asks it before
 * its own requests take a free channel or start a transfer with a server
 * 580h+n, and tells it when they give them back:
 *   SDO_CLIENT_GATE_TAKE_CHANNEL  a request of the node's own wants free
 *                                 channel arg: true = take it; false = it
 *                                 is lent elsewhere, try another one
 *   SDO_CLIENT_GATE_FREE_CHANNEL  channel arg is free again (idle, nothing
 *                                 queued on it) after the node's own use or
 *                                 a lease
 *   SDO_CLIENT_GATE_TAKE_SERVER   a transfer of the node's own wants server
 *                                 node-ID arg: false = reserved elsewhere,
 *                                 the request waits as for a busy server
 *   SDO_CLIENT_GATE_FREE_SERVER   no transfer of the node's own runs with
 *                                 node-ID arg, none ended by its own abort
 *                                 less than 100 ms ago (see
 *                                 sdo_client_lease)
 * A request that met a refusal is retried from the tick (every 100 ms)
 * until it starts, and at once whenever a lease ends. The gate runs on
 * the owning thread inside the core's calls: it must not call back into
 * the node. Installing it announces every free channel (and, for
 * transfers already running, takes their servers).
 */
typedef enum sdo_client_gate_op {
	SDO_CLIENT_GATE_TAKE_CHANNEL,
	SDO_CLIENT_GATE_FREE_CHANNEL,
	SDO_CLIENT_GATE_TAKE_SERVER,
	SDO_CLIENT_GATE_FREE_SERVER,
} sdo_client_gate_op;

typedef bool (*sdo_client_gate_fn)(void *ctx, sdo_client_gate_op op, uint8_t arg);
/* Install (fn NULL: remove) the gate. */
void sdo_client_set_gate(co_node *node, sdo_client_gate_fn fn, void *ctx);
/* The gate's owner freed a server or a channel outside the core's calls
 * (after sdo_client_lease_end, say): the requests it refused are tried
 * now, not at the next retry. Nothing is done when none waits. */
void sdo_client_gate_kick(co_node *node, uint64_t now_us);

/* Lease the given channel, which the gate lent out (it is idle and the
 * node's own requests do not hold it), toward node_id's server, which the
 * gate reserved: sdo_client_lease without the search. Same returns; the
 * checks that remain (the server busy or settling, -EALREADY; no receiver,
 * -ENOSPC; the channel not idle or held by the node's own requests,
 * -EBUSY) fail only when the gate's bookkeeping and the pool disagree. */
int sdo_client_lease_channel(co_node *node, uint8_t channel, uint8_t node_id, sdo_client_raw_fn fn,
			     void *arg, uint64_t now_us);
/* Point the leased channel at node_id's server instead, without giving it
 * back in between (the gateway hands a lease that ended well to the same
 * requester's next transfer, docs/gateway.md): 0, -ENOENT (not leased),
 * -EINVAL, -EALREADY (that server busy or settling), -ENOSPC. Requests of
 * the node's own waiting for the old server may start. */
int sdo_client_lease_move(co_node *node, uint8_t channel, uint8_t node_id, uint64_t now_us);
/* -ENOENT if the channel is not leased. */
int sdo_client_lease_send(co_node *node, uint8_t channel, const uint8_t d[8]);
/* Give the channel back to the pool (waiting requests may start). */
int sdo_client_lease_end(co_node *node, uint8_t channel, uint64_t now_us);

/* A frame of the server of the running relayed request with this tag
 * (its relay brought it): handled like a frame from the bus. 0, or
 * -ENOENT (no such request runs: a late frame). */
int sdo_client_relay_recv(co_node *node, uint64_t tag, const uint8_t d[8], uint64_t now_us);

/* Requests waiting in the pool for a channel. */
unsigned sdo_client_pool_waiting(const co_node *node);

/* Requests on the channel (running + queued). */
unsigned sdo_client_pending(const co_node *node, uint8_t channel);
uint8_t sdo_client_channel_count(const co_node *node);
/* Name of the channel's state ("idle", "upload segment", "block download
 * ack", "start failed", "leased", ...); "?" for a bad channel. */
const char *sdo_client_state_to_string(const co_node *node, uint8_t channel);

#endif /* COGW_CORE_SDO_CLIENT_H */
