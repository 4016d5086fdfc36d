/* SPDX-License-Identifier: MIT */
/*
 * core/pdo_scan.h - the manager's PDO layout step: read a slave's PDO
 * records over SDO (CiA 301 §7.5.2.35-38: 1400h..15FFh/1600h..17FFh of its
 * RPDOs, 1800h..19FFh/1A00h..1BFFh of its TPDOs) into the line's table of
 * learned layouts (core/pdo_layout.h, source SCAN). A step of the CiA
 * 302-2 boot slave process, after the configure step (so what is read is
 * the configured device) and before error control: co_pdo_scan_line_step
 * has the signature of the manager's hook (co_manager_config.pdo_layout).
 *
 * Walk, TPDOs first, then RPDOs, n = 0, 1, ...:
 *   1. communication sub 1 (COB-ID). Abort 06020000h (no object) or
 *      06090011h (no sub-index): the device has no more PDOs of that
 *      direction. Bit 31 set: an invalid PDO, not kept, its mapping not
 *      read (counted in invalid[]). Valid but the node's room
 *      (pdo_scan_max) is full: counted in dropped[], mapping not read.
 *   2. the other communication subs: TPDO 2, 3, 5, 6; RPDO 2, 5 (a sub
 *      the device does not have, 06090011h, reads as 0);
 *   3. mapping sub 0, then subs 1..N (each 1..64 bits, at most 64 in all,
 *      else the scan fails with 06040042h).
 *   n stops at 512 (CO_PDO_MAX) at the latest.
 * Then the layout is committed. SDO cannot tell a data type: an entry is
 * typed from the node's type list (its EDS and the configuration's
 * "types"), else type 0 (an unsigned integer of its length); RPDO dummy
 * entries (0001h..0007h) keep the type they name.
 *
 * Any other abort (or no answer) stops the scan: the node's layout stays
 * invalid, the result names the object and the abort code; the boot goes
 * on (the manager reports it in its boot event, docs/mailbox.md).
 *
 * Requests go through the node's SDO client pool, one at a time per node.
 * A boot-up of the node (co_pdo_scan_line_on_event) invalidates its
 * layout and ends a running scan (disowned: its answer is ignored, like
 * the manager's, core/manager_int.h): the next boot learns it again.
 *
 * The line object is the caller's (embed it; no allocation). Pure code,
 * owning thread only.
 */
#ifndef COGW_CORE_PDO_SCAN_H
#define COGW_CORE_PDO_SCAN_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "core/co.h"
#include "core/event.h"
#include "core/fsm.h"
#include "core/pdo_layout.h"

typedef enum co_pdo_scan_state {
	CO_PDO_SCAN_IDLE = 0,
	CO_PDO_SCAN_COB,   /* communication sub 1 of PDO n */
	CO_PDO_SCAN_COMM,  /* the other communication subs */
	CO_PDO_SCAN_COUNT, /* mapping sub 0 */
	CO_PDO_SCAN_ENTRY, /* mapping sub 1..N */
	CO_PDO_SCAN_DONE,
	CO_PDO_SCAN_FAILED,
	CO_PDO_SCAN_N_STATES
} co_pdo_scan_state;

const char *co_pdo_scan_state_to_string(int state);

typedef enum co_pdo_scan_outcome {
	CO_PDO_SCAN_LEARNT = 0, /* committed to the table */
	CO_PDO_SCAN_ABORTED,    /* an abort or a bad mapping stopped it */
	CO_PDO_SCAN_CANCELLED,  /* a boot-up or co_pdo_scan_line_cancel_all */
} co_pdo_scan_outcome;

const char *co_pdo_scan_outcome_to_string(int outcome);

typedef struct co_pdo_scan_result {
	uint8_t node_id;
	uint8_t outcome;     /* co_pdo_scan_outcome */
	uint16_t n[2];       /* valid PDOs kept, [co_pdo_dir] (device's) */
	uint16_t dropped[2]; /* valid PDOs beyond the room, not kept */
	uint16_t invalid[2]; /* PDOs with COB-ID bit 31 set */
	uint32_t abort;      /* ABORTED: the abort code */
	uint16_t index;      /* ABORTED: the object being read */
	uint8_t sub;
} co_pdo_scan_result;

typedef void (*co_pdo_scan_done_fn)(void *ctx, const co_pdo_scan_result *r, uint64_t now_us);

/* The scan of one node. */
typedef struct co_pdo_scan {
	co_fsm fsm;
	struct co_pdo_scan_line *line;
	uint8_t node_id;
	uint8_t dir;   /* co_pdo_dir being read */
	uint16_t n;    /* PDO number - 1 being read */
	uint8_t step;  /* COMM: position in the list of subs; ENTRY: sub */
	uint8_t count; /* ENTRY: mapping sub 0 */
	uint16_t bits; /* ENTRY: mapped so far */
	bool starting; /* in co_pdo_scan_line_step: no done() */
	uint64_t tag;  /* of the request in flight, 0 = none */
	uint32_t seq;
	uint8_t rd[4];
	co_pdo_layout_pdo cur; /* the PDO being read */
	co_pdo_scan_result res;
} co_pdo_scan;

/* What the line knows of one node (set before the first boot, read-only
 * after). */
typedef struct co_pdo_scan_node {
	bool scan;                       /* learnt by SDO (pdo learn/auto, no file) */
	bool from_file;                  /* its layout came from a file at start-up */
	bool scan_if_reconfigured;       /* a file node whose 1F22h:n changed is
	                                  * scanned instead (its pdo is not off) */
	const co_pdo_layout_type *types; /* sorted (co_pdo_layout_type_find) */
	size_t n_types;
} co_pdo_scan_node;

typedef struct co_pdo_scan_line {
	co_node *node;
	co_pdo_layout *table;      /* NULL: nothing learnt on this line */
	co_pdo_scan job[127];      /* job[n - 1] scans node n */
	co_pdo_scan_node cfg[128]; /* by node-ID */
	uint16_t cdcf_crc[128];    /* 1F22h:n when bound (file nodes) */
	uint32_t sdo_timeout_ms;   /* per frame, 0 = the SDO client's */
	co_pdo_scan_done_fn done;  /* the owner's report (to the manager:
	                              * co_manager_pdo_layout_done) */
	void *done_ctx;
} co_pdo_scan_line;

/*
 * Bind to the node and the table; cfg[] must be filled before (memset and
 * then set per node). Notes the 1F22h:n of file nodes: a different concise
 * DCF at their boot means their file no longer describes them.
 */
void co_pdo_scan_line_init(co_pdo_scan_line *l, co_node *node, co_pdo_layout *table,
			   co_pdo_scan_done_fn done, void *done_ctx);
/*
 * The PDO layout step of node n (the manager's hook; ctx = the line).
 * Returns 0 when there is nothing to learn (a node that is not scanned,
 * or whose file layout still holds), 1 when a scan started (done()
 * reports it, never from inside this call; a scan of the node that still
 * runs is cancelled first), -ENOBUFS when the first request cannot be
 * queued (the SDO client pool is full).
 */
int co_pdo_scan_line_step(void *ctx, uint8_t node_id, uint64_t now_us);
/* Every core event of the node: a boot-up invalidates that node's layout
 * and cancels its scan (done() reports CANCELLED). */
void co_pdo_scan_line_on_event(co_pdo_scan_line *l, const co_event *ev, uint64_t now_us);
/* Node n left the network list or its configuration changed at run time
 * (docs/config.md "Nodes at run time"): its scan is cancelled (no report
 * to the manager's boot) and its layout invalidated; cfg[n] is the
 * caller's to set again. */
void co_pdo_scan_line_forget(co_pdo_scan_line *l, uint8_t node_id, uint64_t now_us);
/* Cancel every running scan (done() reports CANCELLED for each). */
void co_pdo_scan_line_cancel_all(co_pdo_scan_line *l, uint64_t now_us);
bool co_pdo_scan_running(const co_pdo_scan *job);

#endif /* COGW_CORE_PDO_SCAN_H */
