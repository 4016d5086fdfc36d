/* SPDX-License-Identifier: MIT */
/*
 * core/co.h - one CANopen core instance (one per CAN line).
 *
 * The seam between protocol and world:
 *   frames in:   co_node_recv(node, &frame, now_us)
 *   time in:     co_node_tick(node, now_us)        (at or after the deadline)
 *   frames out:  cfg.send(cfg.send_ctx, &frame)
 *   events out:  cfg.event(cfg.event_ctx, &event)
 *   next timer:  co_node_next_deadline_us(node)    (UINT64_MAX = none)
 *
 * Time is uint64_t microseconds of a monotonic clock, read once per loop
 * iteration by the caller. The core has no global state: two nodes in one
 * process (two lines, or two ends of a unit test) never touch each other.
 * Only the thread that owns the node may call into it; callbacks run on that
 * thread, synchronously, and may call back into the node (e.g. submit the
 * next SDO request from a completion event).
 *
 * ---------------------------------------------------------------------------
 * HOW TO ADD A SERVICE (e.g. core/nmt.c, core/pdo.c, core/heartbeat.c)
 *
 * 1. Write core/<svc>.h and core/<svc>.c; the .c includes
 *    core/co_internal.h. State lives in a struct you allocate in your init
 *    op and hang in your typed slot of struct co_node (node->nmt,
 *    node->pdo, ...; add one in core/co_internal.h, NULL until init).
 * 2. Define the ops:  const co_service co_svc_<svc> = { .name = "nmt",
 *    .init = ..., .fini = ..., .tick = ..., .reset_comm = ... };
 *    - init(node): allocate, read your objects from node->od (1017h...),
 *      install OD hooks on them, register receivers with co_rx_register().
 *      Return 0 or -errno (node creation then fails and fini runs).
 *    - fini(node): free; must accept a half-initialised slot.
 *    - tick(node, now_us): run expired timers, return your next deadline
 *      (UINT64_MAX if none). Called at least when the node's deadline
 *      expires, possibly earlier: compare against your own timers.
 *    - reset_comm(node): after 1000h..1FFFh went back to defaults.
 * 3. Whenever you arm a timer outside tick (in a receive handler, an API
 *    call or a hook), call co_node_deadline_lower(node, t).
 * 4. Hook up: add `&co_svc_<svc>,` to the service table in core/co.c (one
 *    line). Order in that table = init order = tick order.
 * 5. Emit events with co_node_emit(); append your kinds to core/event.h.
 *    Send frames with co_node_send().
 * ---------------------------------------------------------------------------
 */
#ifndef COGW_CORE_CO_H
#define COGW_CORE_CO_H

#include <stdbool.h>
#include <stdint.h>

#include "core/event.h"
#include "core/frame.h"
#include "core/od.h"

#define CO_NO_DEADLINE UINT64_MAX

typedef struct co_node co_node;

/* Send one frame. Return 0, or a negative errno if it could not be queued
 * (counted in co_node_stats.tx_failed and reported as CO_EV_TX_FAILED).
 * It must only queue: calling co_node_recv() of any node from inside it
 * (a loopback shortcut) would re-enter a state machine that is still in
 * the middle of sending, e.g. a block transfer's sub-block. */
typedef int (*co_send_fn)(void *ctx, const co_frame *f);
typedef void (*co_event_fn)(void *ctx, const co_event *ev);

typedef struct co_node_config {
	uint8_t node_id; /* 1..127, or 255 = LSS unconfigured */
	co_od *od;       /* required; NOT owned by the node */
	co_send_fn send; /* required */
	void *send_ctx;
	co_event_fn event; /* optional */
	void *event_ctx;

	/* Zero means "default" for every field below. */
	uint16_t rx_max;       /* receiver pool (default 512) */
	uint16_t rx_ext_max;   /* distinct 29-bit ids (default 32) */
	bool report_unhandled; /* emit CO_EV_RX_UNHANDLED */

	/* SDO server (see core/sdo_server.h) */
	uint8_t sdo_server_count;       /* channels 1200h.. (default 1) */
	uint32_t sdo_server_timeout_ms; /* per frame (default 1000) */
	uint8_t sdo_server_blksize;     /* block size offered (default 127) */
	bool sdo_server_no_block;       /* refuse block transfers (0x05040001) */
	bool sdo_server_lenient_size;   /* accept a too long expedited write
	                                 * if the extra bytes are zero */
	uint32_t sdo_stage_size;        /* staging buffer per channel for
	                                 * check-before-write (default 1024) */

	/* SDO client (see core/sdo_client.h) */
	uint8_t sdo_client_count;            /* channels 1280h.. (default 0) */
	uint16_t sdo_client_queue_len;       /* requests per channel (default 8) */
	uint16_t sdo_client_pool_len;        /* requests waiting for any channel
	                                 * (default queue_len x count) */
	uint32_t sdo_client_timeout_ms;      /* per frame, for requests that give
	                                 * none (default 1000) */
	uint32_t sdo_client_block_threshold; /* auto: block at >= this size
	                                      * (default 128; UINT32_MAX = never) */
	uint8_t sdo_client_blksize;          /* requested in block upload (127) */

	/* LSS (CiA 305, see core/lss_master.h and core/lss_slave.h) */
	bool lss_master;                               /* run an LSS master (7E5h out, 7E4h in) */
	uint32_t lss_timeout_ms;                       /* confirmed services, identify windows
	                             * (default 1000) */
	uint32_t lss_scan_step_ms;                     /* Fastscan, per step (default 100) */
	uint8_t lss_queue_len;                         /* master requests queued (default 8) */
	bool lss_slave;                                /* run an LSS slave (answers 7E5h) */
	bool lss_slave_constant_id;                    /* node-ID fixed: store answers error 1 */
	const struct lss_slave_hooks *lss_slave_hooks; /* optional */
	void *lss_slave_ctx;
} co_node_config;

/* Counters: plain data, read at any time by the owning thread. */
typedef struct co_node_stats {
	uint64_t rx_frames;    /* frames given to co_node_recv */
	uint64_t rx_invalid;   /* malformed frames (len > 8, bad id) */
	uint64_t rx_unhandled; /* no receiver registered */
	uint64_t tx_frames;
	uint64_t tx_failed;
} co_node_stats;

int co_node_create(co_node **out, const co_node_config *cfg);
void co_node_destroy(co_node *node); /* accepts NULL */

/* Feed one received frame. Returns 0, or -EINVAL for a malformed frame
 * (counted, ignored). */
int co_node_recv(co_node *node, const co_frame *f, uint64_t now_us);
/* Run timers. Returns the next deadline (same as co_node_next_deadline_us). */
uint64_t co_node_tick(co_node *node, uint64_t now_us);
/* Absolute time at which co_node_tick must run next; CO_NO_DEADLINE if
 * nothing is pending. May be early (a tick then does nothing), never late. */
uint64_t co_node_next_deadline_us(const co_node *node);

co_od *co_node_od(const co_node *node);
uint8_t co_node_id(const co_node *node);
const co_node_stats *co_node_get_stats(const co_node *node);

/* Reset communication: 1000h..1FFFh to defaults, then every service's
 * reset_comm op (SDO COB-IDs back to the predefined set, ...). */
void co_node_reset_comm(co_node *node, uint64_t now_us);
/* Reset application: every object to defaults, then reset communication. */
void co_node_reset_app(co_node *node, uint64_t now_us);

/* ======================================================================
 * For the services of core/, not for the application. The node's fields
 * and what only core/ calls are in core/co_internal.h.
 * ====================================================================== */

/* Receive dispatch: O(1) for 11-bit ids (a direct table of 2048 heads,
 * like the kernel's rx_sff), binary search over a small sorted table for
 * 29-bit ids. Several receivers may share an id (called in registration
 * order). Handles are small integers >= 0. */
typedef void (*co_rx_fn)(co_node *node, void *arg, const co_frame *f, uint64_t now_us);

/* flags: CO_FRAME_EXT for a 29-bit id. RTR frames are delivered to the same
 * receiver (check f->flags). Returns a handle >= 0, -EINVAL, -ENOSPC. */
int co_rx_register(co_node *node, uint32_t id, uint8_t flags, co_rx_fn fn, void *arg);
/* Move a receiver to another id (e.g. an SDO client changing target). */
int co_rx_move(co_node *node, int handle, uint32_t id, uint8_t flags);
/* Detach the receiver from its id but keep the handle (a disabled channel). */
int co_rx_disable(co_node *node, int handle);
int co_rx_unregister(co_node *node, int handle);
/* Frames delivered to this receiver so far. */
uint64_t co_rx_hits(const co_node *node, int handle);

/* Send through the node's callback, counted in co_node_stats (tx_frames,
 * or tx_failed plus CO_EV_TX_FAILED). 0 or the callback's errno. */
int co_node_send(co_node *node, const co_frame *f);
/* Emit an event (no-op without an event callback). */
void co_node_emit(co_node *node, co_event *ev);
/* A service armed a timer at t: make sure the node wakes up by then. */
void co_node_deadline_lower(co_node *node, uint64_t t);

typedef struct co_service {
	const char *name;
	int (*init)(co_node *node);
	void (*fini)(co_node *node);
	uint64_t (*tick)(co_node *node, uint64_t now_us);
	void (*reset_comm)(co_node *node, uint64_t now_us);
	/* Optional: the node's own NMT state changed (enum co_nmt_state
	 * value, core/nmt.h). Called by co_node_nmt_changed() for every
	 * service in table order, after the change took effect. */
	void (*nmt_changed)(co_node *node, uint8_t new_state, uint64_t now_us);
} co_service;

#endif /* COGW_CORE_CO_H */
