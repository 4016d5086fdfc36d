/* SPDX-License-Identifier: MIT */
/*
 * lines/line_ext.h - the extension seam of a line: how the CiA 302 manager,
 * the CiA 302-7 gateway (or a test) plug into a line thread without lines/
 * knowing them.
 *
 * An extension is an ops table plus a context, given to line_create() in
 * line_params.ext[]. apps/cogwd wires them; lines/ never includes their
 * headers. Every op runs on the line thread (attach/detach: on the thread
 * that calls line_create/line_destroy, while the line thread does not run),
 * so an extension owns its state without locks; other threads reach it
 * only through messages (a cross-line ring, lines/xring.h, whose eventfd
 * is wake_fd, or the mailbox).
 *
 * What an extension can do, op by op (all optional):
 *   attach        at start-up: allocate, create what runs on the line's
 *                 node (line_node(l)), hook OD entries. Its timers are
 *                 the extension's own: poll runs them and returns the
 *                 next deadline.
 *   on_core_event observe every event of the line's core, after the line's
 *                 own handling (mailbox answers and events).
 *   on_command    mailbox commands with cmd_first <= code <= cmd_last
 *                 (checked before the line's own table, extensions in
 *                 order). The mailbox has validated the envelope and the
 *                 client's access; the handler answers now or later with
 *                 mbx_server_respond(line_mbx(l), &req->reply, ...).
 *   on_client_gone a mailbox client left: drop what it waits for.
 *   sdo_route     the routing step of a mailbox SDO transfer with a node
 *                 of a network (MBX_CMD_GW_SDO_*, lines/line_sdo.c): the
 *                 transfer itself is the line's, on its SDO client; the
 *                 extension says how its frames reach that node (this
 *                 line's bus, or a relay) or refuses with an SDO abort
 *                 code. It may later end the transfer with
 *                 sdo_client_cancel_tag(line_node(l), tag, abort, ...)
 *                 (the route failed) or feed it the server's frames
 *                 (sdo_client_relay_recv).
 *   sdo_route_end that transfer ended (its confirmation, exactly once for
 *                 every sdo_route that returned 0): give the route back.
 *   nmt_all       a safety reaction of the line (lines/line_appwd.c: the
 *                 application watchdog, host not ready) wants every node
 *                 in the state of NMT command cs: the extension that is
 *                 the line's NMT master sends it its own way, so that it
 *                 holds the network there (0), or says it is not the
 *                 master (-EPERM). nmt_master asks the same without
 *                 sending anything.
 *   on_wake       wake_fd became readable (the line has read the eventfd
 *                 counter): drain the hand-offs, e.g. xring_pop() until 0.
 *   before_events at the start of every loop iteration, before its
 *                 events are handled: take the hand-offs pushed without
 *                 waking the line (xring_push_quiet), so that whatever
 *                 woke it - a frame, a timer, a mailbox request - finds
 *                 them applied.
 *   poll          once per loop iteration: run what is due at now_us and
 *                 return the next time it needs the line (CO_NO_DEADLINE
 *                 for none); the line sleeps no longer than that.
 *   adopt_node    boot a node outside the configuration (lines/line_scan.c,
 *                 the "boot" policy of unknown_nodes).
 *   node_set      a slave added to, changed in or removed from the line's
 *                 network list at run time by the main thread (a reload,
 *                 line_request_node): the extension that owns the list
 *                 (the manager) applies it and returns 0 or a negative
 *                 errno; the first extension with this op takes it.
 *   node_changed  a node's entry changed (line_node_changed, called by
 *                 the extension that applied it): follow it (the device
 *                 object layer mirrors or releases the node's PDOs).
 *   detach        at line_destroy(), after the thread stopped and before
 *                 the node is destroyed.
 * Rules for every op: never block, never allocate after attach, never
 * call into another line's core.
 */
#ifndef COGW_LINES_LINE_EXT_H
#define COGW_LINES_LINE_EXT_H

#include <stdbool.h>
#include <stdint.h>

#include "core/co.h"
#include "core/pdo_layout.h"
#include "core/sdo_client.h"
#include "mailbox/server.h"

typedef struct line line;

/* How a mailbox SDO transfer with a node of a network reaches it. */
typedef struct line_sdo_route {
	uint8_t node;              /* the node the transfer talks to (this line's bus: the
	               * target itself; relayed: the target behind the relay) */
	sdo_client_relay_fn relay; /* NULL: this line's bus */
	void *relay_ctx;
	uint32_t relay_target; /* see sdo_client_req.relay_target */
} line_sdo_route;

/* A slave added, changed or removed at run time (docs/config.md "Nodes at
 * run time"): the mailbox's fixed part (MBX_CMD_MGR_NODE_SET, validated
 * the same way) and what only the daemon's configuration can give. */
typedef struct line_node_set {
	mbx_mgr_node_set_req req;
	const uint8_t *cdcf; /* 1F22h:n, cdcf_len bytes (NULL, 0 = none);
	                      * valid during the call */
	uint32_t cdcf_len;
	const co_pdo_layout_type *types; /* sorted; must outlive the line */
	size_t n_types;
	bool as_file; /* a reload: the node becomes what the file says,
	               * whether or not the mailbox added or removed it
	               * meanwhile (no duplicate or not-found refusal) */
} line_node_set;

/* What the other extensions hear of a change that was applied. */
typedef struct line_node_news {
	uint8_t node;
	bool removed;
	uint8_t pdo;                     /* 0 off, 1 learn, 2 auto: its PDOs are mirrored */
	const co_pdo_layout_type *types; /* sorted; must outlive the line */
	size_t n_types;
} line_node_news;

typedef struct line_ext_ops {
	const char *name;                  /* for logs */
	int (*attach)(void *ctx, line *l); /* 0 or -errno: line_create fails */
	void (*detach)(void *ctx, line *l);
	void (*on_core_event)(void *ctx, line *l, const co_event *ev);
	uint16_t cmd_first, cmd_last; /* inclusive; 0, 0 = no commands */
	void (*on_command)(void *ctx, line *l, const mbx_request *req);
	void (*on_client_gone)(void *ctx, line *l, uint32_t client);
	void (*on_wake)(void *ctx, line *l);
	void (*before_events)(void *ctx, line *l);
	uint64_t (*poll)(void *ctx, line *l, uint64_t now_us);
	/* 0 (*out filled) or the SDO abort code that refuses the request. */
	uint32_t (*sdo_route)(void *ctx, line *l, uint64_t tag, uint16_t net, uint8_t node,
			      line_sdo_route *out);
	void (*sdo_route_end)(void *ctx, line *l, uint64_t tag);
	/* The line's unknown_nodes policy is "boot" and the identity of
	 * `node`, a node outside the configuration, was read (ident: 1000h,
	 * 1018h:1..4): take it as an optional slave. 0 = its boot began,
	 * -ENOENT = no device file has that identity, another -errno = not
	 * possible. The first extension that has the op decides. */
	int (*adopt_node)(void *ctx, line *l, uint8_t node, const uint32_t ident[5]);
	int (*node_set)(void *ctx, line *l, const line_node_set *set);
	void (*node_changed)(void *ctx, line *l, const line_node_news *info);
	int (*nmt_all)(void *ctx, line *l, uint8_t cs, uint64_t now_us);
	bool (*nmt_master)(void *ctx, line *l);
} line_ext_ops;

typedef struct line_ext {
	const line_ext_ops *ops; /* NULL = unused entry */
	void *ctx;
	int wake_fd; /* eventfd (not EFD_SEMAPHORE: one read resets it) the
	              * line watches when ops->on_wake is set; -1 = none. Not
	              * owned (e.g. xring_mesh_wake_fd()). */
} line_ext;

#define LINE_EXT_MAX 4

/* For extensions, on the line thread (and in attach/detach). */
co_node *line_node(line *l);
mbx_server *line_mbx(line *l);
uint8_t line_index(const line *l);
uint16_t line_network_id(const line *l);
/* The time of the current loop iteration (the one the core got). */
uint64_t line_loop_now_us(const line *l);
/* The slaves' PDO layouts the line was given (line_params.pdo_layout), or
 * NULL. The manager's PDO layout step fills it, the device object layer
 * reads it; both on the line thread. */
co_pdo_layout *line_pdo_layout(line *l);

/*
 * The objects a TPDO's frame carries when an extension builds that frame
 * itself. The device object layer's TPDO that produces a device's RPDO maps
 * one slot object holding the whole frame (docs/devices.md); when the
 * frame's objects are process image objects, it names them here, so that
 * the gateway's fast path (docs/gateway.md "One wake-up per hop") can
 * build the same frame from the image on another line's thread and send
 * it: entries LSB first in frame order, each the low `bits` of its object;
 * `is_signed`: the object holds a signed integer, else an unsigned one - a
 * value its bits cannot hold is not sent that way (the extension refuses
 * it). Set, replaced or cleared (n = 0) by the extension and read by the
 * others, all on the line thread; at most LINE_TPDO_SOURCES_MAX TPDOs of
 * LINE_TPDO_SOURCE_ENTRIES objects (-ENOSPC, -EINVAL: the TPDO keeps its
 * ordinary way).
 */
#define LINE_TPDO_SOURCES_MAX 32u
#define LINE_TPDO_SOURCE_ENTRIES 8u

typedef struct line_tpdo_source {
	uint16_t index;
	uint8_t sub;
	uint8_t bits; /* 1..64 */
	bool is_signed;
} line_tpdo_source;

int line_tpdo_sources_set(line *l, uint16_t nr, const line_tpdo_source *src, uint8_t n);
/* The objects TPDO nr's frame carries, 0 when none were named. */
uint8_t line_tpdo_sources_get(const line *l, uint16_t nr, const line_tpdo_source **src);
/* Raised by every change, for a reader that keeps what it derived. */
uint32_t line_tpdo_sources_generation(const line *l);

/* The answer of an extension's SDO transfer (line_sdo_submit), at its
 * confirmation: abort 0 = done, data/len the uploaded bytes (download:
 * NULL, 0). It must answer `to` exactly once (mbx_server_respond). */
typedef void (*line_sdo_answer_fn)(void *ctx, line *l, const mbx_reply_to *to, uint32_t abort,
				   const uint8_t *data, uint32_t len);

typedef struct line_sdo_xfer {
	bool upload;
	uint8_t node; /* of this line's bus */
	uint16_t index;
	uint8_t sub;
	uint32_t size_hint; /* upload: expected size, 0 = unknown */
	line_sdo_answer_fn answer;
	void *ctx;
} line_sdo_xfer;

/* An SDO transfer on behalf of an extension's mailbox command, run as the
 * line's one mailbox SDO transfer (lines/line_sdo.c: pending slot, budget,
 * chunking, the cancel when the client goes away, MBX_EV_SDO_DONE): a
 * download sends req->data. Refusals (no SDO client, no free slot, ...)
 * are answered here (false); otherwise (true) x->answer answers at the
 * confirmation, exactly once. */
bool line_sdo_submit(line *l, const mbx_request *req, const line_sdo_xfer *x);

/* Node `node`'s heartbeat consumed with time_ms in 1016h (0 = no longer):
 * its entry, else a free one, written through the OD (the consumer loads
 * it again). 0, -ENOSPC (1016h full), -EIO (the entry refused it). Line
 * thread. */
int line_consumer_set(line *l, uint8_t node, uint16_t time_ms);
/* Tell every extension with node_changed (line thread). */
void line_node_changed(line *l, const line_node_news *info);

#endif /* COGW_LINES_LINE_EXT_H */
