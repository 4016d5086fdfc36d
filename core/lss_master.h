/* SPDX-License-Identifier: MIT */
/*
 * core/lss_master.h - LSS master (CiA 305): configure node-IDs and bit
 * rates of LSS slaves, identify them, find unknown ones by Fastscan.
 *
 * Enabled by cfg.lss_master (see core/co.h). Sends on 7E5h, listens on
 * 7E4h.
 *
 * Contract
 * - Every service is asynchronous: lss_master_submit() starts it (or
 *   queues it), received frames and co_node_tick() advance it, and exactly
 *   one CO_EV_LSS_MASTER_DONE (u.lss_master) ends every accepted request,
 *   carrying the caller's tag. If the request names a confirmation
 *   (req.con), it is called exactly once with the same content just
 *   before that event. Neither ever comes from inside lss_master_submit():
 *   a request that ends at once (switch global, a refused send) is
 *   reported from the next co_node_tick() at the same time (the node's
 *   deadline asks for it).
 * - One service at a time per node: LSS answers carry no address, so two
 *   services in flight could not tell their answers apart. Further
 *   requests wait in a FIFO of cfg.lss_queue_len entries allocated at node
 *   creation; -ENOSPC when it is full (never "busy").
 * - Timeouts: confirmed services (switch selective, configure, store,
 *   inquire) wait cfg.lss_timeout_ms (default 1000) for their answer.
 *   Identify services listen for the whole window (same default) and
 *   count the answers: several slaves may answer, and "nobody answered" is
 *   the result LSS_RESULT_NOT_FOUND, not an error. Fastscan listens
 *   cfg.lss_scan_step_ms (default 100) per step; a full scan of all four
 *   fields is 1 + 4 x 32 steps, plus one per field whose bit 0 is 1 (at
 *   most 13.3 s at 100 ms). A known field costs 1 step. Each request may
 *   override its timeout (timeout_ms).
 * - Unconfirmed services: switch global completes as soon as its frame is
 *   out (reported at the next tick). Activate bit timing completes after the switch delay (that is when
 *   the application must switch the master's own controller) and the
 *   master then keeps the bus quiet for a second delay before the next
 *   request, as CiA 305 asks of the slaves.
 * - Node-IDs and bit timing indexes are sent as given (not range checked
 *   here): the slave's error answer is the authority, and testing a
 *   device's range check needs invalid values on the wire. The mailbox
 *   validates what clients send.
 * - Only the thread owning the node may call these.
 */
#ifndef COGW_CORE_LSS_MASTER_H
#define COGW_CORE_LSS_MASTER_H

#include <stdbool.h>
#include <stdint.h>

#include "core/co.h"
#include "core/lss.h"

typedef enum lss_master_service {
	LSS_SVC_NONE = 0,
	LSS_SVC_SWITCH_GLOBAL,       /* mode: lss_state */
	LSS_SVC_SWITCH_SELECTIVE,    /* addr */
	LSS_SVC_CONFIG_NODE_ID,      /* node_id */
	LSS_SVC_CONFIG_BIT_TIMING,   /* table, index */
	LSS_SVC_ACTIVATE_BIT_TIMING, /* delay_ms */
	LSS_SVC_STORE,
	LSS_SVC_INQUIRE_VENDOR, /* -> value */
	LSS_SVC_INQUIRE_PRODUCT,
	LSS_SVC_INQUIRE_REVISION,
	LSS_SVC_INQUIRE_SERIAL,
	LSS_SVC_INQUIRE_NODE_ID,         /* -> node_id */
	LSS_SVC_IDENTIFY_REMOTE,         /* addr (vendor, product, revision low,
	                             * serial low), addr_high (revision high,
	                             * serial high) -> answers */
	LSS_SVC_IDENTIFY_NON_CONFIGURED, /* -> answers */
	LSS_SVC_FASTSCAN,                /* addr + known_mask -> identity */
	LSS_SVC_COUNT
} lss_master_service;

const char *lss_master_service_to_string(lss_master_service s);

typedef enum lss_result {
	LSS_RESULT_OK = 0,      /* done; identify/Fastscan: a slave answered */
	LSS_RESULT_SLAVE_ERROR, /* the slave answered error_code (+ spec) */
	LSS_RESULT_TIMEOUT,     /* no answer to a confirmed service */
	LSS_RESULT_NOT_FOUND,   /* identify/Fastscan: no slave answered */
	LSS_RESULT_SCAN_LOST,   /* Fastscan: a confirmation step went
	                         * unanswered (slave left or reset mid-scan) */
	LSS_RESULT_CANCELLED,   /* lss_master_cancel_all() */
	LSS_RESULT_TX_FAILED,   /* the send callback refused a frame */
} lss_result;

const char *lss_result_to_string(lss_result r);

/* Per-request confirmation (see the contract above). It may submit further
 * requests. */
typedef void (*lss_master_con_fn)(void *arg, const co_ev_lss_master *con);

typedef struct lss_master_req {
	lss_master_service service;
	uint64_t tag;          /* echoed in CO_EV_LSS_MASTER_DONE */
	uint32_t timeout_ms;   /* 0 = the node's default for this service */
	uint8_t mode;          /* SWITCH_GLOBAL: lss_state */
	uint8_t node_id;       /* CONFIG_NODE_ID: 1..127, 255 = unconfigure */
	uint8_t table;         /* CONFIG_BIT_TIMING: selector (0 = CiA table) */
	uint8_t index;         /* CONFIG_BIT_TIMING: index in that table */
	uint16_t delay_ms;     /* ACTIVATE_BIT_TIMING: switch delay */
	uint8_t known_mask;    /* FASTSCAN: bit i set = addr.id[i] is known and
	                      * only confirmed, not scanned */
	lss_address addr;      /* SWITCH_SELECTIVE, IDENTIFY_REMOTE, FASTSCAN */
	lss_address addr_high; /* IDENTIFY_REMOTE: only revision and serial
	                        * (upper bounds) are used */
	lss_master_con_fn con; /* NULL = event only */
	void *con_arg;
} lss_master_req;

/* Queue a request; it starts at once when the master is idle. Returns 0,
 * -ENODEV (no LSS master on this node), -EINVAL (bad service, mode, known
 * mask), -ENOSPC (queue full). */
int lss_master_submit(co_node *node, const lss_master_req *req, uint64_t now_us);

/* Convenience wrappers around lss_master_submit(). */
int lss_master_switch_global_req(co_node *node, lss_state mode, uint64_t tag, uint64_t now_us);
int lss_master_switch_selective_req(co_node *node, const lss_address *addr, uint64_t tag,
				    uint64_t now_us);
int lss_master_config_node_id_req(co_node *node, uint8_t node_id, uint64_t tag, uint64_t now_us);
int lss_master_config_bit_timing_req(co_node *node, uint8_t table, uint8_t index, uint64_t tag,
				     uint64_t now_us);
int lss_master_activate_bit_timing_req(co_node *node, uint16_t delay_ms, uint64_t tag,
				       uint64_t now_us);
int lss_master_store_req(co_node *node, uint64_t tag, uint64_t now_us);
/* service: one of LSS_SVC_INQUIRE_*. */
int lss_master_inquire_req(co_node *node, lss_master_service service, uint64_t tag,
			   uint64_t now_us);
/* lo: vendor, product, revision low, serial low; hi: revision and serial
 * high (vendor/product of hi are ignored). */
int lss_master_identify_remote_req(co_node *node, const lss_address *lo, const lss_address *hi,
				   uint64_t tag, uint64_t now_us);
int lss_master_identify_non_configured_req(co_node *node, uint64_t tag, uint64_t now_us);
/* known may be NULL (nothing known). On LSS_RESULT_OK the found slave is
 * in configuration state and the event carries its full identity. */
int lss_master_fastscan_req(co_node *node, const lss_address *known, uint8_t known_mask,
			    uint64_t tag, uint64_t now_us);

/* End the running request and every queued one with LSS_RESULT_CANCELLED
 * (events in FIFO order). Frames already sent are not taken back. */
void lss_master_cancel_all(co_node *node, uint64_t now_us);

/* Requests running + queued; 0 without a master. */
unsigned lss_master_pending(const co_node *node);

/* States of the master's machine (core/fsm.h), for diagnostics and tests. */
typedef enum lss_master_state {
	LSS_MASTER_IDLE = 0,
	LSS_MASTER_START,      /* sending the request's first frames */
	LSS_MASTER_CONFIRM,    /* confirmed service: waiting for one answer */
	LSS_MASTER_WINDOW,     /* identify: counting answers until the end of
	                        * the window */
	LSS_MASTER_ACTIVATE,   /* activate bit timing: the switch delay */
	LSS_MASTER_FS_RESET,   /* Fastscan: BitChecked 80h sent, anybody? */
	LSS_MASTER_FS_BIT,     /* Fastscan: probing one bit (31..1) */
	LSS_MASTER_FS_CONFIRM, /* Fastscan: a whole field sent, slave moves on */
	LSS_MASTER_DONE_LATER, /* ended inside lss_master_submit(): reported
	                        * from the next tick */
	LSS_MASTER_STATE_COUNT
} lss_master_state;

/* "idle", "confirm", "fs-bit", ...; "?" out of range. */
const char *lss_master_state_to_string(lss_master_state s);
/* State of the node's master; LSS_MASTER_IDLE without one. */
lss_master_state lss_master_state_of(const co_node *node);

/* ---- for core/lss_service.c only ---------------------------------------------- */
int lss_master_init(co_node *node, struct lss_master **out);
void lss_master_fini(struct lss_master *m);
uint64_t lss_master_tick(struct lss_master *m, uint64_t now_us);

#endif /* COGW_CORE_LSS_MASTER_H */
