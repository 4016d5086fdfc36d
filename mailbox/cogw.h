/* SPDX-License-Identifier: MIT */
/*
 * cogw.h - libcogw, the client library of the cogw CANopen gateway daemon.
 *
 *     cogw *h;
 *     if (cogw_open(&h, "main") < 0) ...            // daemon instance name
 *     uint32_t v, abort;
 *     int rc = cogw_sdo_read_u32(h, 0, 5, 0x1018, 1, &v, 1000, &abort);
 *     if (rc == COGW_E_ABORT) printf("abort %08x\n", abort);
 *     else if (rc < 0) printf("%s\n", cogw_strerror(rc));
 *     cogw_close(h);
 *
 * - Every call returns 0 (or a count) on success, or a negative COGW_E_*
 *   code (one error space; cogw_strerror() names it). An SDO or local OD
 *   refusal is COGW_E_ABORT with the CiA 301 abort code in *abort.
 * - `line` is the daemon's CAN line (0-based). The library registers with
 *   a line on first use (its queues are created by cogw_open, mode 0600).
 * - Blocking calls take timeout_ms (0 = the handle's default, 5000 ms) for
 *   the whole exchange with the daemon. SDO timeouts on the bus come back
 *   as COGW_E_ABORT with abort 0x05040000.
 * - Data of any size: the library chunks and reassembles transparently up
 *   to the daemon's limit (1 MiB by default).
 * - Thread-safe: several threads may make calls on one handle at once.
 *   Whichever thread reads the response queue hands each answer to the
 *   caller waiting for its correlation id. A helper thread (asynchronous
 *   answers, lease renewal, restart watch) starts with the first
 *   cogw_send_async(), cogw_subscribe(), cogw_recv(), a registration
 *   with a lease or a wait longer than 200 ms; a handle whose blocking
 *   calls are answered at once has none.
 * - Events: cogw_subscribe() per line and class, then cogw_recv(); for an
 *   epoll loop, watch cogw_event_fd() and call cogw_recv(h, &m, 0) until it
 *   returns COGW_E_AGAIN. cogw_recv() also returns the answers to requests
 *   started with cogw_send_async().
 * - Event loops (epoll, poll, select, asyncio's add_reader): a handle
 *   from cogw_loop_open() has no thread at all; see "For event loops"
 *   below.
 * - Message layouts, command and event codes: mailbox/proto.h;
 *   the protocol: docs/mailbox.md.
 */
#ifndef COGW_H
#define COGW_H

#include <stddef.h>
#include <stdint.h>

#include "mailbox/proto.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct cogw cogw;

/* ---- errors ------------------------------------------------------------- */

enum cogw_err {
	COGW_OK = 0,
	/* reported by the daemon (same values as enum mbx_status) */
	COGW_E_VERSION = MBX_E_VERSION,
	COGW_E_MALFORMED = MBX_E_MALFORMED,
	COGW_E_UNKNOWN_CMD = MBX_E_UNKNOWN_CMD,
	COGW_E_BAD_LINE = MBX_E_BAD_LINE,
	COGW_E_NOT_REGISTERED = MBX_E_NOT_REGISTERED,
	COGW_E_ACCESS = MBX_E_ACCESS,
	COGW_E_PARAM = MBX_E_PARAM,
	COGW_E_TOO_BIG = MBX_E_TOO_BIG,
	COGW_E_BUSY = MBX_E_BUSY,
	COGW_E_FULL = MBX_E_FULL,
	COGW_E_QUEUE = MBX_E_QUEUE,
	COGW_E_TIMEOUT = MBX_E_TIMEOUT,
	COGW_E_ABORT = MBX_E_ABORT,
	COGW_E_STATE = MBX_E_STATE,
	COGW_E_UNSUPPORTED = MBX_E_UNSUPPORTED,
	COGW_E_SEQUENCE = MBX_E_SEQUENCE,
	COGW_E_OVERFLOW = MBX_E_OVERFLOW,
	COGW_E_INTERNAL = MBX_E_INTERNAL,
	COGW_E_SHUTDOWN = MBX_E_SHUTDOWN,
	COGW_E_LSS = MBX_E_LSS,
	COGW_E_NOT_FOUND = MBX_E_NOT_FOUND,
	COGW_E_NO_ANSWER = MBX_E_NO_ANSWER, /* the device, not the daemon */
	COGW_E_NO_MEMORY = MBX_E_NO_MEMORY, /* transfer memory budget spent */
	/* found by the library */
	COGW_E_NO_DAEMON = -100, /* the line's command queue does not exist */
	COGW_E_SYSTEM = -101,    /* a system call failed: errno tells */
	COGW_E_INVAL = -102,     /* bad argument */
	COGW_E_NOMEM = -103,
	COGW_E_AGAIN = -104,     /* cogw_recv: nothing there (yet) */
	COGW_E_TRUNCATED = -105, /* answer larger than the buffer; *len
	                          * tells the full size, buffer filled */
	COGW_E_CLOSED = -106,    /* handle is closing */
	COGW_E_PROTOCOL = -107,  /* the daemon sent something unexpected */
	/* the daemon restarted while the request was under way: it may or may
	 * not have been carried out; the next call registers again */
	COGW_E_RESTARTED = -108,
	/* cogw_open: the message-queue memory of this user (RLIMIT_MSGQUEUE,
	 * shared by all its processes, the daemon's queues included when it
	 * runs as the same user) is used up; the kernel says EMFILE */
	COGW_E_QUEUE_LIMIT = -109,
	/* cogw_loop_send: not sent, nothing waited for: the line's command
	 * queue is full (wait for cogw_loop_cmd_fd() to be writable), the
	 * handle's response queue could not hold one more answer (take the
	 * answers in), or the line registers again after a daemon restart
	 * (retry after cogw_loop_tick()) */
	COGW_E_WOULDBLOCK = -110,
};

const char *cogw_strerror(int err);

/* ---- handle ------------------------------------------------------------- */

typedef struct cogw_options {
	const char *instance; /* daemon instance ("main"); required */
	unsigned queue_mode;  /* own queues, 0 = 0600 (0620 when the daemon
	                        * runs as a non-root user of your group) */
	unsigned resp_depth;  /* 0 = 32, clamped to fs.mqueue.msg_max */
	unsigned event_depth; /* 0 = 32, same clamp */
	unsigned msg_size;    /* own queues' message size, 0 = 1024 */
	unsigned timeout_ms;  /* default for calls given 0, 0 = 5000 */
} cogw_options;

int cogw_open(cogw **h, const char *instance);
int cogw_open_opts(cogw **h, const cogw_options *opts);
/* Unregisters from every line, removes the queues. Accepts NULL. */
void cogw_close(cogw *h);

/* ---- local object dictionary of a line (the daemon's own OD) ----------- */

int cogw_od_read(cogw *h, unsigned line, uint16_t index, uint8_t sub, void *buf, size_t cap,
		 size_t *len, unsigned timeout_ms, uint32_t *abort);
int cogw_od_write(cogw *h, unsigned line, uint16_t index, uint8_t sub, const void *data, size_t len,
		  unsigned timeout_ms, uint32_t *abort);

/* ---- remote SDO (the daemon is the SDO client) -------------------------- */

/* mode: 0 auto, 1 expedited, 2 segmented, 3 block. sdo_timeout_ms: per
 * SDO frame on the bus (0 = line default). */
typedef struct cogw_sdo_opts {
	uint8_t mode;
	uint32_t sdo_timeout_ms;
} cogw_sdo_opts;

int cogw_sdo_read(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub, void *buf,
		  size_t cap, size_t *len, unsigned timeout_ms, uint32_t *abort);
int cogw_sdo_write(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub,
		   const void *data, size_t len, unsigned timeout_ms, uint32_t *abort);
int cogw_sdo_read_ex(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub,
		     const cogw_sdo_opts *o, void *buf, size_t cap, size_t *len,
		     unsigned timeout_ms, uint32_t *abort);
int cogw_sdo_write_ex(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub,
		      const cogw_sdo_opts *o, const void *data, size_t len, unsigned timeout_ms,
		      uint32_t *abort);

/* The same with a node of network `net` (CiA 302-7 routing through the
 * daemon, docs/gateway.md): the line's 1F2Ch picks the local line, or the
 * next router. net = the line's own network is a plain transfer. Routing
 * refusals are COGW_E_ABORT with *abort 0A000001h (no route), 0A000002h
 * (no answer), 0A000003h (busy) or 060A0023h (no client free). */
int cogw_sdo_read_net(cogw *h, unsigned line, uint16_t net, uint8_t node, uint16_t index,
		      uint8_t sub, const cogw_sdo_opts *o, void *buf, size_t cap, size_t *len,
		      unsigned timeout_ms, uint32_t *abort);
int cogw_sdo_write_net(cogw *h, unsigned line, uint16_t net, uint8_t node, uint16_t index,
		       uint8_t sub, const cogw_sdo_opts *o, const void *data, size_t len,
		       unsigned timeout_ms, uint32_t *abort);

/* Typed helpers: values are little-endian on the bus; a reply of the wrong
 * size is COGW_E_ABORT with abort 0x06070010 (type/length mismatch).
 * Strings are NUL-terminated (COGW_E_TRUNCATED if cap is too small).
 * A DOMAIN is cogw_sdo_read/write with a buffer. */
int cogw_sdo_read_u8(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub, uint8_t *v,
		     unsigned timeout_ms, uint32_t *abort);
int cogw_sdo_read_u16(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub,
		      uint16_t *v, unsigned timeout_ms, uint32_t *abort);
int cogw_sdo_read_u32(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub,
		      uint32_t *v, unsigned timeout_ms, uint32_t *abort);
int cogw_sdo_read_u64(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub,
		      uint64_t *v, unsigned timeout_ms, uint32_t *abort);
int cogw_sdo_read_float(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub, float *v,
			unsigned timeout_ms, uint32_t *abort);
int cogw_sdo_read_string(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub, char *s,
			 size_t cap, unsigned timeout_ms, uint32_t *abort);
int cogw_sdo_write_u8(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub, uint8_t v,
		      unsigned timeout_ms, uint32_t *abort);
int cogw_sdo_write_u16(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub,
		       uint16_t v, unsigned timeout_ms, uint32_t *abort);
int cogw_sdo_write_u32(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub,
		       uint32_t v, unsigned timeout_ms, uint32_t *abort);
int cogw_sdo_write_u64(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub,
		       uint64_t v, unsigned timeout_ms, uint32_t *abort);
int cogw_sdo_write_float(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub, float v,
			 unsigned timeout_ms, uint32_t *abort);
int cogw_sdo_write_string(cogw *h, unsigned line, uint8_t node, uint16_t index, uint8_t sub,
			  const char *s, unsigned timeout_ms, uint32_t *abort);

/* ---- NMT, nodes, PDO, EMCY, raw CAN ------------------------------------- */

/* cs: 0x01 start, 0x02 stop, 0x80 pre-operational, 0x81 reset node,
 * 0x82 reset communication. node 0 = all nodes. */
int cogw_nmt(cogw *h, unsigned line, uint8_t cs, uint8_t node, unsigned timeout_ms);
/* Fills up to cap entries; returns the number of nodes known (>= 0). */
int cogw_node_table(cogw *h, unsigned line, mbx_node_entry *tab, size_t cap, unsigned timeout_ms);
int cogw_pdo_request(cogw *h, unsigned line, uint16_t tpdo, unsigned timeout_ms);
/* Supervision of the line's own RPDOs: counters into *st, the RPDOs with
 * a deadline or length episode open into tab (at most cap). Returns how
 * many RPDOs have one open (>= 0), or an error. */
int cogw_rpdo_status(cogw *h, unsigned line, mbx_rpdo_status *st, mbx_rpdo_fault_entry *tab,
		     size_t cap, unsigned timeout_ms);
int cogw_pdo_read(cogw *h, unsigned line, uint16_t index, uint8_t sub, void *buf, size_t cap,
		  size_t *len, unsigned timeout_ms);
/* trigger: send event-driven TPDOs that map the object now. */
int cogw_pdo_write(cogw *h, unsigned line, uint16_t index, uint8_t sub, const void *data,
		   size_t len, int trigger, unsigned timeout_ms);
int cogw_emcy_send(cogw *h, unsigned line, uint16_t code, uint8_t reg, const uint8_t msef[5],
		   unsigned timeout_ms);
/* frames: id | MBX_RAW_EXT / MBX_RAW_RTR, len 0..8; n 1..32. */
int cogw_raw_send(cogw *h, unsigned line, const mbx_raw_frame *frames, size_t n,
		  unsigned timeout_ms);

/* ---- device objects of the line's slaves (docs/devices.md) ---------------- */

/* The learned PDO layouts with their mirror (MBX_CMD_DEV_LAYOUT): node
 * 1..127, or 0 for every node the line knows. The answer (its format in
 * docs/mailbox.md "Device objects") into buf; *len its length
 * (COGW_E_TRUNCATED when larger than cap). cogw_dev_layout_check walks it. */
int cogw_dev_layout(cogw *h, unsigned line, uint8_t node, void *buf, size_t cap, size_t *len,
		    unsigned timeout_ms);
/* The nodes in a DEV_LAYOUT answer (>= 0), or COGW_E_PROTOCOL when its
 * counts do not add up to its length. */
int cogw_dev_layout_check(const void *buf, size_t len);

/* This line's ends of the forwarded device objects (gateway.forward) with
 * their counters: *n entries into out (COGW_E_TRUNCATED beyond cap). */
int cogw_dev_forwards(cogw *h, unsigned line, mbx_dev_forward *out, size_t cap, size_t *n,
		      unsigned timeout_ms);

/* Watch a device object: MBX_EV_DEV_VALUE events (cogw_recv, whatever the
 * subscriptions) with each value the mirror receives, at most one per
 * min_interval_ms (the latest when it ends). *resp (optional): the type
 * the values carry and the device's TPDO. COGW_E_NOT_FOUND: no TPDO of the
 * node maps it; COGW_E_STATE: not mirrored (pdo not "auto", or it did not
 * fit); COGW_E_FULL: the line's watch table is full; COGW_E_ABORT 06070010:
 * a type that cannot carry it. Watching it again changes the interval. */
int cogw_dev_watch(cogw *h, unsigned line, const mbx_dev_obj_req *obj, uint32_t min_interval_ms,
		   mbx_dev_watch_resp *resp, unsigned timeout_ms, uint32_t *abort);
int cogw_dev_unwatch(cogw *h, unsigned line, const mbx_dev_obj_req *obj, unsigned timeout_ms);
/* Read a device object: from the mirror when its value is at most
 * max_age_ms old (0 = the line's default, UINT32_MAX = any age; obj->flags
 * MBX_DEV_SDO_ONLY: never), else by SDO. *v says which (via, age_ms); the
 * value's bytes go to buf (*len; COGW_E_TRUNCATED beyond cap). */
int cogw_dev_read(cogw *h, unsigned line, const mbx_dev_obj_req *obj, uint32_t max_age_ms,
		  mbx_dev_value *v, void *buf, size_t cap, size_t *len, unsigned timeout_ms,
		  uint32_t *abort);
/* Write a device object (CiA 301 encoding of obj->type or the known type):
 * by the device's RPDO when the mirror produces it (resp->held: sent once
 * every object of that RPDO has a value), else (or with MBX_DEV_SDO_ONLY)
 * by SDO. *resp (optional) says which. */
int cogw_dev_write(cogw *h, unsigned line, const mbx_dev_obj_req *obj, const void *data, size_t len,
		   mbx_dev_write_resp *resp, unsigned timeout_ms, uint32_t *abort);
/* The fixed part and the value of an MBX_EV_DEV_VALUE event (or a
 * DEV_READ answer): 0, or COGW_E_PROTOCOL. *data points into payload. */
int cogw_dev_value_parse(const void *payload, size_t len, mbx_dev_value *v, const uint8_t **data);

/* ---- typed values (CiA 301 data types), for every client ------------------ */

typedef struct cogw_type {
	const char *name;     /* short name: "u16", "i24", "r32", "bool", "string" */
	const char *cia_name; /* "UNSIGNED16", ... */
	uint16_t type;        /* MBX_T_* */
	uint8_t size;         /* bytes; 0 = variable (strings, DOMAIN) */
} cogw_type;

/* By short or CiA name, case-insensitive; NULL if unknown. */
const cogw_type *cogw_type_find(const char *name);
/* By MBX_T_* number; NULL if not a basic type. */
const cogw_type *cogw_type_of(uint16_t type);
/* "bool, u8, ..., domain" for help and errors. */
const char *cogw_type_names(void);
/* A value's text into out (NUL-terminated): integers in decimal, reals
 * the shortest text that reads back the same, BOOLEAN "true"/"false",
 * VISIBLE_STRING its characters, TIME_OF_DAY/TIME_DIFFERENCE "DAYS MS",
 * the others hex bytes "01 02 03". Returns the text's length,
 * COGW_E_INVAL (len is not the type's size) or COGW_E_TRUNCATED. */
int cogw_value_format(uint16_t type, const uint8_t *data, size_t len, char *out, size_t cap);
/* A text as a value of the type: integers decimal or 0x hex within the
 * type's range, reals, bool 0/1/true/false, a VISIBLE_STRING's
 * characters, hex bytes for the other strings and DOMAIN, "DAYS MS" for
 * the times. 0, COGW_E_INVAL (not a value of the type), COGW_E_PARAM (out
 * of the type's range), COGW_E_TRUNCATED (more than cap bytes). */
int cogw_value_parse(uint16_t type, const char *text, uint8_t *out, size_t cap, size_t *len);

/* ---- LSS master (CiA 305) ------------------------------------------------ */

/* Generic: cmd = MBX_CMD_LSS_*, fields of req as proto.h documents. */
int cogw_lss(cogw *h, unsigned line, uint16_t cmd, const mbx_lss_req *req, mbx_lss_resp *resp,
	     unsigned timeout_ms);
int cogw_lss_switch_global(cogw *h, unsigned line, uint8_t mode, unsigned timeout_ms);
int cogw_lss_switch_selective(cogw *h, unsigned line, uint32_t vendor, uint32_t product,
			      uint32_t revision, uint32_t serial, unsigned timeout_ms);
int cogw_lss_set_node_id(cogw *h, unsigned line, uint8_t node, unsigned timeout_ms);
int cogw_lss_set_bit_timing(cogw *h, unsigned line, uint8_t table, uint8_t index,
			    unsigned timeout_ms);
int cogw_lss_activate_bit_timing(cogw *h, unsigned line, uint16_t delay_ms, unsigned timeout_ms);
int cogw_lss_store(cogw *h, unsigned line, unsigned timeout_ms);
/* what: 0x5A vendor, 0x5B product, 0x5C revision, 0x5D serial, 0x5E node */
int cogw_lss_inquire(cogw *h, unsigned line, uint8_t what, uint32_t *value, unsigned timeout_ms);
/* Returns 1 if non-configured slaves answered, 0 if none. */
int cogw_lss_identify_nonconf(cogw *h, unsigned line, unsigned timeout_ms);
/* id[4] = vendor, product, revision, serial of the slave found. */
int cogw_lss_fastscan(cogw *h, unsigned line, uint32_t id[4], unsigned timeout_ms);

/* ---- line status, store/restore, mailbox counters ------------------------ */

int cogw_line_status(cogw *h, unsigned line, mbx_line_status *st, unsigned timeout_ms);
/* sub: 1 all, 2 communication, 3 application, 4..127 manufacturer. */
int cogw_store(cogw *h, unsigned line, uint8_t sub, unsigned timeout_ms);
/* The line's gateway: counters and its routes (at most cap of them, *n =
 * how many the daemon sent). */
int cogw_gw_routes(cogw *h, unsigned line, mbx_gw_status *st, mbx_gw_route *routes, size_t cap,
		   size_t *n, unsigned timeout_ms);
/* The same, and the routed sessions running now (at most s_cap of them,
 * *n_s = how many the daemon sent = st->active). Arrays may be NULL. */
int cogw_gw_status(cogw *h, unsigned line, mbx_gw_status *st, mbx_gw_route *routes, size_t cap,
		   size_t *n, mbx_gw_session *sessions, size_t s_cap, size_t *n_s,
		   unsigned timeout_ms);
int cogw_restore(cogw *h, unsigned line, uint8_t sub, unsigned timeout_ms);

/* ---- the line's CiA 302-2 manager (MBX_CMD_MGR_*) ------------------------- */

/* State, flags, bit lists, counters and first error of the line. */
int cogw_mgr_status(cogw *h, unsigned line, mbx_mgr_status *st, unsigned timeout_ms);
/* Diagnostics of one node 1..127: last boot status, boot time/count, EMCYs. */
int cogw_mgr_node_diag(cogw *h, unsigned line, uint8_t node, mbx_mgr_node_diag *d,
		       unsigned timeout_ms);
/* Boot node 1..127 again, or the whole network (node 0). */
int cogw_mgr_boot(cogw *h, unsigned line, uint8_t node, unsigned timeout_ms);
/* Start the network (when 1F80h leaves that to the application). */
int cogw_mgr_start(cogw *h, unsigned line, unsigned timeout_ms);
/* Request NMT (1F82h): node 1..127 or 128 = all; cmd 4, 5, 6, 7, 127. */
int cogw_mgr_request_nmt(cogw *h, unsigned line, uint8_t node, uint8_t cmd, unsigned timeout_ms);
int cogw_mgr_reset_counters(cogw *h, unsigned line, unsigned timeout_ms);
/* A node added to the manager's network list, changed, or removed without
 * restarting the line (docs/mailbox.md "Nodes at run time"): req->op
 * MBX_NODE_ADD / CHANGE / REMOVE; cdcf (cdcf_len bytes, NULL/0 = none) is
 * the concise DCF for 1F22h:n. Answered once the objects are written and
 * the node's boot has started (its progress: MGR_BOOT events).
 * COGW_E_PARAM (own node-ID, not a concise DCF), COGW_E_STATE (network
 * boot running, slave mode, ADD of an assigned node), COGW_E_NOT_FOUND
 * (CHANGE/REMOVE of a node not assigned), COGW_E_TOO_BIG (the DCF exceeds
 * the room of 1F22h:n). */
int cogw_mgr_node_set(cogw *h, unsigned line, const mbx_mgr_node_set_req *req, const uint8_t *cdcf,
		      size_t cdcf_len, unsigned timeout_ms);
int cogw_mgr_node_remove(cogw *h, unsigned line, uint8_t node, unsigned timeout_ms);
int cogw_mbx_stats(cogw *h, unsigned line, mbx_stats_wire *st, unsigned timeout_ms);
int cogw_ping(cogw *h, unsigned line, unsigned timeout_ms);

/* ---- objects the client owns (docs/application.md) ------------------------ */

/* Claim an object of the line's own node declared for your user (obj->type
 * 0, obj->kind as declared), or create one in 2000h..5FFFh / 6000h..9FFFh
 * (type, access, max_size for strings and DOMAIN; def/def_len its default,
 * NULL/0 = zeros). Held: the daemon keeps the value (write it with
 * cogw_od_write or cogw_pdo_write; MBX_EV_APP_WRITTEN tells you of the
 * writes of others). Served: every read and write reaches you as
 * MBX_EV_APP_IND (subscribed or not): answer each with cogw_app_answer
 * within its deadline_ms. COGW_E_ACCESS: another client owns it, or it is
 * not yours to claim; COGW_E_FULL: the line's or your bound; COGW_E_PARAM:
 * the description does not match. Claims end with the registration (a
 * daemon restart, cogw_close): claim again. Needs write access. */
int cogw_app_claim(cogw *h, unsigned line, const mbx_app_claim_req *obj, const void *def,
		   size_t def_len, unsigned timeout_ms);
int cogw_app_release(cogw *h, unsigned line, uint16_t index, uint8_t sub, unsigned timeout_ms);
/* Answer indication `ind`: abort 0 with the value (a read) or nothing (a
 * write: accepted, applied), or a CiA 301 abort code (refused: nothing
 * applied, the requester gets the code). COGW_E_PARAM: not an indication
 * of yours that is still open (it ended: MBX_EV_APP_CANCEL), or a read's
 * value that does not fit the object (the requester got 06040047h). */
int cogw_app_answer(cogw *h, unsigned line, uint32_t ind, uint32_t abort, const void *data,
		    size_t len, unsigned timeout_ms);
/* All the data of a write indication (when inline_len < size). */
int cogw_app_ind_data(cogw *h, unsigned line, uint32_t ind, void *buf, size_t cap, size_t *len,
		      unsigned timeout_ms);
/* The line's owned objects (at most cap into objs, *n of them) and its
 * indication counters. */
int cogw_app_list(cogw *h, unsigned line, mbx_app_status *st, mbx_app_obj *objs, size_t cap,
		  size_t *n, unsigned timeout_ms);
/* MBX_EV_APP_IND / MBX_EV_APP_WRITTEN payloads: the fixed part and the
 * inline bytes of the value. 0 or COGW_E_PROTOCOL. */
int cogw_app_ind_parse(const void *payload, size_t len, mbx_ev_app_ind *ind, const uint8_t **data);
int cogw_app_written_parse(const void *payload, size_t len, mbx_ev_app_written *w,
			   const uint8_t **data);

/* ---- events and asynchronous requests ------------------------------------ */

/* Add classes (MBX_EVC_*). With MBX_EVC_RAW, filters (0..4, NULL/0 = all
 * frames) replace the previous ones. */
int cogw_subscribe(cogw *h, unsigned line, uint32_t classes, const mbx_raw_filter *filters,
		   size_t n_filters, unsigned timeout_ms);
int cogw_unsubscribe(cogw *h, unsigned line, uint32_t classes, unsigned timeout_ms);

/* What cogw_recv() returns: an event, or the answer to cogw_send_async(). */
typedef struct cogw_msg {
	uint8_t kind; /* MBX_KIND_EVENT or MBX_KIND_RESPONSE */
	uint8_t line;
	uint16_t code;    /* event code (mbx_event) or command code */
	int status;       /* response: 0 or COGW_E_*; event: 0 */
	uint32_t abort;   /* CiA abort code, 0 = none */
	uint64_t corr;    /* correlation id (0 for unrelated events) */
	uint32_t dropped; /* messages lost before this one (overflow) */
	size_t len;       /* payload bytes at data */
	uint8_t *data;    /* payload; valid until cogw_msg_release() */
} cogw_msg;

/* Start a command without waiting: payload as proto.h defines for cmd
 * (any size for data commands: chunked here). *corr receives the
 * correlation id that the answer (and related events) will carry. */
int cogw_send_async(cogw *h, unsigned line, uint16_t cmd, const void *payload, size_t len,
		    uint64_t *corr);
/* Next event or asynchronous answer, waiting up to timeout_ms (0 = do not
 * wait, -1 = forever). COGW_E_AGAIN if none came. Release with
 * cogw_msg_release(). Validates event payload sizes. */
int cogw_recv(cogw *h, cogw_msg *m, int timeout_ms);
void cogw_msg_release(cogw_msg *m);
/* A descriptor that is readable when cogw_recv() has something for you
 * (opened on the first call), or a negative cogw_err. */
int cogw_event_fd(cogw *h);

/* ---- for event loops ------------------------------------------------------ */

/*
 * A loop handle: no thread inside the library, one descriptor for the
 * application's loop, sends that never wait. It is driven by one thread,
 * its loop (the blocking calls work on it too, from that thread: use them
 * to set up, e.g. cogw_subscribe(); they wait like on any handle).
 *
 *     cogw *h;
 *     cogw_loop_open(&h, &(cogw_options){ .instance = "main" });
 *     cogw_loop_attach(h, 0, 0);             // register with line 0
 *     int fd = cogw_loop_fd(h);
 *     for (;;) {
 *         struct pollfd pf = { .fd = fd, .events = POLLIN };
 *         poll(&pf, 1, cogw_loop_timeout_ms(h));
 *         cogw_loop_tick(h);
 *         cogw_msg m;
 *         while (cogw_loop_recv(h, &m) == 0) { ...; cogw_msg_release(&m); }
 *         // cogw_loop_send(h, 0, MBX_CMD_SDO_UPLOAD, &rq, sizeof rq, 0, &corr);
 *     }
 *
 * docs/mailbox.md "Event loops" has the whole story.
 */

/* Open a loop handle (options as cogw_open_opts). */
int cogw_loop_open(cogw **h, const cogw_options *opts);
/* Register with a line (timeout_ms 0: the handle's default). The one call
 * of the loop interface that waits: the registration's answer. After a
 * daemon restart the handle registers again by itself (cogw_loop_tick),
 * and subscribes again to what it had. 0 or a cogw_err. */
int cogw_loop_attach(cogw *h, unsigned line, unsigned timeout_ms);
/* The descriptor to wait on (POLLIN / EPOLLIN / select's read set /
 * asyncio add_reader): readable while an answer or an event is waiting,
 * or a message of the daemon that cogw_loop_recv() takes in on the way
 * (a chunk of a longer answer). Level-triggered; stays the same for the
 * handle's life; closed by cogw_close(). */
int cogw_loop_fd(cogw *h);
/* Start a command (payload as cogw_send_async) without waiting. Its answer
 * comes through cogw_loop_recv() with the correlation id put in *corr; if
 * none came within timeout_ms (0: the handle's default), the answer is
 * status COGW_E_TIMEOUT, and a daemon restart under way is
 * COGW_E_RESTARTED: every request started gets exactly one answer.
 * Returns 0; COGW_E_WOULDBLOCK (not sent: the line's command queue is
 * full; or as many requests are under way as the handle's response queue
 * holds (resp_depth), their answers on cogw_loop_fd() make room; or the
 * line registers again after a restart); COGW_E_NO_DAEMON
 * (the daemon is gone); COGW_E_NOT_REGISTERED (cogw_loop_attach the line
 * first); or another cogw_err. A command too large for one message goes
 * in chunks, started only when the queue has room for all of them (or
 * for a queue's depth of them); another client filling it meanwhile, or
 * chunks beyond the depth, make this wait for room, up to timeout_ms. */
int cogw_loop_send(cogw *h, unsigned line, uint16_t cmd, const void *payload, size_t len,
		   unsigned timeout_ms, uint64_t *corr);
/* The line's command queue, to wait for POLLOUT after COGW_E_WOULDBLOCK
 * (writable: room for one message, which other clients may take first;
 * the same descriptor across daemon restarts). A descriptor, or
 * COGW_E_NOT_REGISTERED. */
int cogw_loop_cmd_fd(cogw *h, unsigned line);
/* The next answer or event, never waiting: 0, or COGW_E_AGAIN when none
 * is there (an answer's chunks are taken in on the way). Answers before
 * events. Release m with cogw_msg_release(). The descriptor stays
 * readable while more waits: a loop may take one message per wake-up. */
int cogw_loop_recv(cogw *h, cogw_msg *m);
/* How long the loop may wait (ms, >= 0) before cogw_loop_tick() has
 * something to do: a lease to renew, a daemon restart to look for (every
 * second at most), a request's time-out. Counted from the latest
 * cogw_loop_tick() or cogw_loop_send() (no clock read of its own). */
int cogw_loop_timeout_ms(cogw *h);
/* Do what is due: renew leases (PING), notice a daemon restart (the
 * line's requests answered COGW_E_RESTARTED, the line registered again),
 * answer requests past their time-out with COGW_E_TIMEOUT. Cheap when
 * nothing is due; call it after every wait. */
void cogw_loop_tick(cogw *h);

/* Library-side counters (overflows seen, async answers dropped). */
typedef struct cogw_stats {
	uint64_t overflow_flags;   /* messages that carried MBX_F_OVERFLOW */
	uint64_t dropped_reported; /* sum of their dropped counts */
	uint64_t stray_responses;  /* answers nobody waited for */
	uint64_t async_dropped;    /* async answers lost (ring full) */
} cogw_stats;
void cogw_get_stats(cogw *h, cogw_stats *st);

#ifdef __cplusplus
}
#endif

#endif /* COGW_H */
