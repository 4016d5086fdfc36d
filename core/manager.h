/* SPDX-License-Identifier: MIT */
/*
 * core/manager.h - the CANopen manager of one line: network boot-up and
 * supervision (CiA 302-2), Request NMT (1F82h), configuration request
 * (1F25h) and the line's diagnostics.
 *
 * Configuration surface: the manager node's own OD, read live (an SDO or
 * mailbox write takes effect at the next decision that reads it):
 *   1F80h NMT start-up     bit 0 NMT master, bit 1 start all slaves with
 *                          one broadcast, bit 2 the manager does not start
 *                          itself, bit 3 the application starts the
 *                          slaves, bit 4 reset all nodes on an error of a
 *                          mandatory slave, bit 6 stop all nodes instead
 *                          (bit 4 wins when both are set)
 *   1F81h:n slave assignment  bit 0 slave, bit 2 boot it, bit 3 mandatory,
 *                          bit 4 keep-alive, bits 8-15 retry (life time)
 *                          factor, bits 16-31 guard time in ms
 *   1F84h..1F88h:n         expected 1000h, 1018h:1..4 (0 = do not check)
 *   1F89h boot time (ms)   mandatory slaves must have booted by then
 *                          (0 = wait for ever)
 *   1016h                  heartbeat consumer entries (error control)
 *   1F82h:n (n = 128: all) Request NMT; 1F25h:n "conf" = boot node n again
 * co_od_add_manager_defaults() adds what is missing.
 *
 * Machines (core/fsm.h), each state citing the CiA 302-2 step:
 * - one per line (enum co_mgr_state): NMT start-up / network boot;
 * - one per node 1..127: the boot slave process. Nodes boot in parallel,
 *   bounded by the SDO client pool (max_parallel nodes in their SDO steps
 *   at once, from the 1000h read to the end of the configure step).
 *
 * Inputs: the owner forwards every core event of the node to
 * co_manager_on_event() (boot-ups, heartbeat/guarding, EMCY; SDO answers
 * come through per-request confirmations) and calls co_manager_tick() at or
 * after co_manager_next_deadline_us(). Outputs: NMT and SDO frames through
 * the node, and events through the node's event callback (CO_EV_MGR_*,
 * u.mgr). The manager also filters NMT commands from the bus addressed to
 * its own node (co_nmt_set_rx_filter).
 *
 * Pure code: no I/O, time comes in as a parameter; owning thread only.
 * Functions return 0 or a negative errno.
 */
#ifndef COGW_CORE_MANAGER_H
#define COGW_CORE_MANAGER_H

#include <stdbool.h>
#include <stdint.h>

#include "core/co.h"

/* 1F80h bits */
#define CO_MGR_1F80_MASTER (1u << 0)
#define CO_MGR_1F80_START_ALL (1u << 1)
#define CO_MGR_1F80_NO_SELF_START (1u << 2)
#define CO_MGR_1F80_APP_STARTS_SLAVES (1u << 3)
#define CO_MGR_1F80_RESET_ALL_ON_ERROR (1u << 4)
#define CO_MGR_1F80_FLYING_MASTER (1u << 5)
#define CO_MGR_1F80_STOP_ALL_ON_ERROR (1u << 6)

/* 1F81h bits */
#define CO_MGR_1F81_SLAVE (1u << 0)
#define CO_MGR_1F81_BOOT (1u << 2)
#define CO_MGR_1F81_MANDATORY (1u << 3)
#define CO_MGR_1F81_KEEP_ALIVE (1u << 4)
#define CO_MGR_1F81_VERIFY_SW (1u << 5)
#define CO_MGR_1F81_UPDATE_SW (1u << 6)
#define CO_MGR_1F81_RESTORE (1u << 7)
#define CO_MGR_1F81_RETRY_FACTOR(v) (((v) >> 8) & 0xFFu)
#define CO_MGR_1F81_GUARD_MS(v) ((v) >> 16)

/* 1F25h signature "conf" (little-endian) */
#define CO_MGR_CONF_SIGNATURE 0x666E6F63u
#define CO_MGR_ALL_NODES 128u

/* Line state of the CiA 302-2 network boot (docs/cogwctl.md "manager"). */
typedef enum co_mgr_state {
	CO_MGR_SLAVE = 0,      /* 1F80h bit 0 clear: plain NMT slave */
	CO_MGR_RESETTING,      /* reset communication of the network */
	CO_MGR_BOOTING,        /* boot slave processes running */
	CO_MGR_WAIT_MANDATORY, /* first pass over, mandatory slaves missing */
	CO_MGR_BOOTED,         /* booted, network not started */
	CO_MGR_OPERATIONAL,    /* network started */
	CO_MGR_STOPPED,        /* network stopped (request or error reaction) */
	CO_MGR_PREOP,          /* network pre-operational (request) */
	CO_MGR_FATAL,          /* a device on the manager's node-ID */
	CO_MGR_STATE_COUNT
} co_mgr_state;

/* "slave", "resetting", "booting", "wait-mandatory", "booted",
 * "operational", "stopped", "pre-operational", "fatal" */
const char *co_mgr_state_to_string(uint8_t state);

/* Flags beside the state (low nibble; docs/cogwctl.md "manager"). */
#define CO_MGR_F_OPTIONAL_MISSING \
	0x01u /* optional missing/wrong, or an
                                         * unexpected node is present */
#define CO_MGR_F_MANDATORY_MISSING 0x02u
#define CO_MGR_F_SLAVE_OPERATIONAL 0x04u
#define CO_MGR_F_MANAGER_OPERATIONAL 0x08u

/* Steps of the boot slave process, as reported in CO_EV_MGR_BOOT. */
typedef enum co_mgr_step {
	CO_MGR_STEP_ASSIGNMENT = 0, /* 1F81h bit 0 */
	CO_MGR_STEP_KEEP_ALIVE,     /* keep-alive state check */
	CO_MGR_STEP_DEVICE_TYPE,    /* 1000h vs 1F84h */
	CO_MGR_STEP_VENDOR,         /* 1018h:1 vs 1F85h */
	CO_MGR_STEP_PRODUCT,        /* 1018h:2 vs 1F86h */
	CO_MGR_STEP_REVISION,       /* 1018h:3 vs 1F87h */
	CO_MGR_STEP_SERIAL,         /* 1018h:4 vs 1F88h */
	CO_MGR_STEP_CONFIGURE,      /* CiA 302-3 hook */
	CO_MGR_STEP_ERRCTRL,        /* start of error control */
	CO_MGR_STEP_START,          /* NMT start per 1F80h */
	CO_MGR_STEP_BOOT_TIME,      /* 1F89h ran out before this node booted */
	CO_MGR_STEP_SOFTWARE,       /* CiA 302-3 software manager hook (runs
	                             * between serial and configure) */
	CO_MGR_STEP_PDO_LAYOUT,     /* the slave's PDO layout learnt (runs
	                             * between configure and error control;
	                             * core/pdo_scan.h) */
	CO_MGR_STEP_COUNT
} co_mgr_step;

/* "assignment", "keep-alive", "device-type", "vendor-id", "product-code",
 * "revision", "serial", "configure", "error-control", "start",
 * "boot-time", "software", "pdo-layout" */
const char *co_mgr_step_to_string(uint8_t step);

/* CiA 302-2 boot status letters this module reports (0 = booted / none);
 * A not in 1F81h, B no answer to 1000h, C 1000h differs from 1F84h,
 * D/M/N/O 1018h:1/2/3/4 differ from 1F85h/1F86h/1F87h/1F88h, E heartbeat
 * event after boot, F node guarding event, J configuration failed (302-3
 * hook), K no heartbeat during the start of error control, L the slave was
 * operational already (keep-alive; informational). */
const char *co_mgr_status_to_string(char status);

/* What CO_EV_MGR_NODE reports. */
typedef enum co_mgr_node_what {
	CO_MGR_NODE_UNEXPECTED = 0, /* a node not in 1F81h showed up (once) */
	CO_MGR_NODE_LATE,           /* an assigned node booted after the
	                             * network boot had ended */
	CO_MGR_NODE_LOST,           /* error control lost: status E or F */
	CO_MGR_NODE_BACK,           /* error control of a lost node resumed */
	CO_MGR_NODE_DUPLICATE,      /* two devices seem to share this ID:
	                             * value = the NMT state a heartbeat
	                             * contradicting its boot-up reported, or
	                             * CO_MGR_DUP_SDO_ANSWERS */
	CO_MGR_NODE_OWN_ID,         /* a frame on the manager's own node-ID:
	                             * value = its COB-ID; 700h+id (boot-up or
	                             * heartbeat) = a device uses it, the line
	                             * goes FATAL; 080h+id, 580h+id: reported,
	                             * boot and supervision go on */
	CO_MGR_NODE_NMT_IGNORED,    /* an NMT command to the manager was
	                             * ignored; value = cs, sub = target */
	CO_MGR_NODE_KEEP_OP,        /* KEEP_OP: started again; value = state
	                             * it had left to */
	CO_MGR_NODE_REQUEST_NMT,    /* 1F82h / request: value = command */
	CO_MGR_NODE_ERROR_REACTION, /* 1F80h reaction ran: value = cs sent
	                             * (0 = that node alone) */
	CO_MGR_NODE_PROGRAM,        /* program download progress (302-3
	                             * software manager; reported by the
	                             * owner): value = bytes sent, expected =
	                             * image size */
	CO_MGR_NODE_WHAT_COUNT
} co_mgr_node_what;

const char *co_mgr_node_what_to_string(uint8_t what);

/* CO_MGR_NODE_DUPLICATE value: two answers to one SDO request. */
#define CO_MGR_DUP_SDO_ANSWERS 0x100u

/* 1F82h values */
enum co_mgr_nmt_request {
	CO_MGR_REQ_STOP = 4,
	CO_MGR_REQ_START = 5,
	CO_MGR_REQ_RESET_NODE = 6,
	CO_MGR_REQ_RESET_COMM = 7,
	CO_MGR_REQ_PREOP = 127,
};
/* 1F82h read values */
enum co_mgr_nmt_read {
	CO_MGR_NODE_UNKNOWN = 0,
	CO_MGR_NODE_MISSING = 1,
};

/*
 * The 302-3 configure step: called when a node reaches it (it still holds
 * its boot slot; SDO requests go through the client pool). Return 0 when the node is configured
 * (or needs nothing), 1 when the outcome follows later through
 * co_manager_configure_done(), or a negative errno for a failure (J).
 * With 1F81h:n bit 7 (restore configuration) the step may reset the node
 * itself: a boot-up of node n during the step is then left to the hook
 * (core/cfgmgr.h co_cfgmgr_line_configure) instead of restarting its boot.
 */
typedef int (*co_mgr_configure_fn)(void *ctx, uint8_t node_id, uint64_t now_us);

/*
 * The 302-3 "check software" step (before the configure step, CiA 302-2
 * boot slave process): called when a node reaches it, holding its boot
 * slot. Return 0 when the software is right (or not checked: 1F81h bit 5
 * clear), 1 when the outcome follows later through
 * co_manager_software_done(), or a negative errno for status G (the
 * program download objects are not configured).
 * core/swmgr.h co_swmgr_line_check has this signature.
 */
typedef int (*co_mgr_software_fn)(void *ctx, uint8_t node_id, uint64_t now_us);

/*
 * The PDO layout step (after the configure step, so the layout read is the
 * configured one; before error control): called when a node reaches it,
 * holding its boot slot. Return 0 when there is nothing to learn, 1 when
 * the outcome follows later through co_manager_pdo_layout_done(), or a
 * negative errno when it could not start. The step never fails the boot:
 * a layout that could not be learnt is reported in the step's boot event
 * (abort code, object) and the boot goes on. core/pdo_scan.h
 * co_pdo_scan_line_step has this signature.
 */
typedef int (*co_mgr_pdo_layout_fn)(void *ctx, uint8_t node_id, uint64_t now_us);

typedef struct co_manager_config {
	uint8_t max_parallel;          /* nodes in their SDO steps at once
	                             * (0 = the node's SDO client channels);
	                             * requests go through the client pool */
	uint32_t sdo_timeout_ms;       /* per SDO frame during the boot (500) */
	uint32_t reset_wait_ms;        /* longest wait for a boot-up after reset
	                             * communication (1000) */
	uint32_t retry_ms;             /* retry interval of a node that did not
	                             * answer (1000); optional nodes for ever,
	                             * mandatory ones until 1F89h runs out */
	uint32_t scan_ms;              /* search for missing assigned nodes
	                             * every scan_ms after the boot (0 = off) */
	bool accept_remote_nmt;        /* NMT commands from the bus to our own
	                             * node are applied (default: ignored and
	                             * counted while we are NMT master) */
	bool no_autostart;             /* do not run the network boot at the
	                             * first tick (the application calls
	                             * co_manager_boot_network) */
	co_mgr_configure_fn configure; /* NULL: nothing to configure */
	void *configure_ctx;
	co_mgr_software_fn software; /* NULL: software not checked */
	void *software_ctx;
	co_mgr_pdo_layout_fn pdo_layout; /* NULL: no layout learnt */
	void *pdo_layout_ctx;
} co_manager_config;

typedef struct co_manager co_manager;

#define CO_MGR_EMCY_HISTORY 8

typedef struct co_mgr_emcy_rec {
	uint64_t time_us;
	uint16_t code;
	uint8_t reg;
	uint8_t msef[5];
} co_mgr_emcy_rec;

/* Diagnostics of one node. */
typedef struct co_mgr_node_diag {
	uint32_t assignment; /* 1F81h:n when last read */
	uint8_t step;        /* co_mgr_step of the last boot event */
	char status;         /* CiA letter of the last failure, 0 = none */
	uint32_t abort;      /* SDO abort code of that failure (0 = none) */
	uint16_t index;      /* object of that failure */
	uint8_t sub;
	uint32_t value;   /* value read at that failure */
	uint8_t bs_state; /* boot slave machine state (internal index) */
	bool booting;
	bool booted;
	uint64_t boot_started_us;
	uint64_t boot_time_us; /* duration of the last successful boot */
	uint32_t boot_count;   /* successful boots */
	uint32_t fail_count;   /* failed attempts */
	uint8_t emcy_count;    /* entries in emcy[] (<= 8) */
	uint8_t emcy_next;     /* ring position of the next entry */
	co_mgr_emcy_rec emcy[CO_MGR_EMCY_HISTORY];
} co_mgr_node_diag;

/* Bit lists: bit n of word n / 32 = node n (0..127). */
typedef struct co_mgr_bits {
	uint32_t w[4];
} co_mgr_bits;

typedef struct co_mgr_diag {
	uint8_t state; /* co_mgr_state */
	uint8_t flags; /* CO_MGR_F_* */
	co_mgr_bits assigned, present, booted, operational, stopped, preop, mismatch, errctrl_lost,
		emcy_active;
	uint8_t first_error_node;  /* 0 = none since the last reset */
	char first_error_status;   /* boot status letter, 0 = an EMCY */
	uint32_t first_error_code; /* EMCY error code, or the SDO abort code
	                            * of the boot failure (0 = none) */
	uint32_t nmt_ignored;      /* NMT commands to us ignored */
	uint32_t unexpected;       /* unexpected nodes reported */
	uint32_t duplicates;       /* duplicate node-IDs reported */
	uint32_t errctrl_events;   /* error-control losses of booted slaves */
	uint32_t keep_op_restarts;
	uint32_t network_boots;
	uint32_t own_id_frames; /* EMCY, SDO answers or malformed error-control
	                         * frames on the manager's own node-ID */
} co_mgr_diag;

static inline bool co_mgr_bit(const co_mgr_bits *b, unsigned n)
{
	return n < 128 && (b->w[n / 32] >> (n % 32)) & 1u;
}

/* Create a manager on `node` (not attached to anything: the owner
 * forwards events and ticks). Installs the 1F82h/1F25h hooks and the NMT
 * receive filter. -ENOMEM, -EINVAL (no SDO client channel). */
int co_manager_create(co_manager **out, co_node *node, const co_manager_config *cfg);
/* Accepts NULL. Cancels the manager's SDO requests; call it before the
 * node is destroyed. */
void co_manager_destroy(co_manager *m);

/* Every core event of the node (events the manager emits itself are
 * ignored). */
void co_manager_on_event(co_manager *m, const co_event *ev);
/* Run timers; returns the next deadline (CO_NO_DEADLINE = none). */
uint64_t co_manager_tick(co_manager *m, uint64_t now_us);
uint64_t co_manager_next_deadline_us(const co_manager *m);

/* Re-run the network boot (NMT start-up from the reset on). Leaves FATAL.
 * -EPERM in slave mode (1F80h bit 0 clear). */
int co_manager_boot_network(co_manager *m, uint64_t now_us);
/* Run the boot slave process of one node again (in a stopped network:
 * once the network leaves STOPPED, the node held stopped until then).
 * -EINVAL for a bad node, -ENOENT if not assigned, -EPERM in slave mode or
 * FATAL. */
int co_manager_boot_node(co_manager *m, uint8_t node_id, uint64_t now_us);
/* 1F81h:n was written at run time (a write of 1F81h:n through the OD calls
 * it; docs/config.md "Nodes at run time"): an assigned node's boot slave
 * process runs again with the objects as they are now (1F84h..1F88h,
 * 1F22h:n, 1016h), a node no longer assigned leaves the network list: its
 * boot is aborted and it is no longer supervised or reported. 0 also in
 * slave mode (read at the next network boot), -EAGAIN while the network
 * boot runs, -EINVAL for a bad node or the manager's own node-ID. */
int co_manager_node_reassigned(co_manager *m, uint8_t node_id, uint64_t now_us);
/* Start the network (when 1F80h leaves it to the application): the
 * manager itself, then the slaves. -EAGAIN while a mandatory slave has not
 * booted, -EPERM in slave mode or FATAL. A stopped network always leaves
 * STOPPED: the nodes held stopped (and missing mandatory ones) are booted,
 * and the network starts once every mandatory slave has booted. */
int co_manager_start_network(co_manager *m, uint64_t now_us);
/* Request NMT (the 1F82h write): node 1..127 or CO_MGR_ALL_NODES, cmd one
 * of enum co_mgr_nmt_request. -EINVAL, -EPERM (slave mode), -EAGAIN
 * (start of the network while a mandatory slave is missing; from STOPPED
 * as co_manager_start_network). While the network is STOPPED the manager
 * sends no SDO request: a node that boots up, or whose boot is asked for,
 * is held stopped and booted when the network leaves STOPPED (start,
 * pre-operational, or a new network boot). */
int co_manager_request_nmt(co_manager *m, uint8_t node_id, uint8_t cmd, uint64_t now_us);
/* The 1F82h read value of node n (0 unknown, 1 missing, 4, 5, 127). */
uint8_t co_manager_node_nmt_state(const co_manager *m, uint8_t node_id);
/* The 302-3 configure step ended (abort 0 = configured). On a failure
 * (J), index:sub is the object refused and entry the concise DCF entry
 * that wrote it (1-based; 0 = a write outside the concise DCF, such as
 * 1020h or 1010h); on success entry is the number of entries written (0 =
 * nothing downloaded, e.g. 1020h matched). The boot event carries it as
 * its value. */
int co_manager_configure_done(co_manager *m, uint8_t node_id, uint32_t abort, uint16_t index,
			      uint8_t sub, uint32_t entry, uint64_t now_us);
/* The 302-3 check software step ended: status 0 = right software (or
 * updated), 'G', 'H' or 'I' = failed, with the object, the value read
 * there and the abort code; a passed step may name what was seen too (the
 * program state 1F51h:1 when the software is not checked). The boot event
 * carries index:sub and value. -EINVAL (bad node or letter), -ENOENT (node
 * not in that step). */
int co_manager_software_done(co_manager *m, uint8_t node_id, char status, uint32_t abort,
			     uint16_t index, uint8_t sub, uint32_t value, uint64_t now_us);
/* The PDO layout step ended. abort 0: learnt, with tpdos/rpdos kept and
 * dropped (beyond the table's room); else the abort code and the object
 * whose read failed. The boot event carries value = tpdos | rpdos << 16,
 * expected = dropped_tpdos | dropped_rpdos << 16, abort and index:sub; the
 * boot goes on to error control either way. -EINVAL (bad node), -ENOENT
 * (node not in that step). */
int co_manager_pdo_layout_done(co_manager *m, uint8_t node_id, uint32_t abort, uint16_t index,
			       uint8_t sub, uint32_t kept, uint32_t dropped, uint64_t now_us);
/* KEEP_OP (`keep_op` in docs/config.md): a node that leaves OPERATIONAL
 * without being told is started again. */
int co_manager_set_keep_op(co_manager *m, uint8_t node_id, bool on);
/* The NMT state a node is put in after its boot once the network runs
 * (CO_NMT_OPERATIONAL, the default; CO_NMT_PRE_OPERATIONAL: left as it is;
 * CO_NMT_STOPPED). In a stopped network a booted node is stopped whatever
 * its target. -EINVAL for another state or node. */
int co_manager_set_target_state(co_manager *m, uint8_t node_id, uint8_t nmt_state);

uint8_t co_manager_state(const co_manager *m);
uint8_t co_manager_flags(const co_manager *m);
/* Snapshot of the diagnostics (bit lists computed now). */
void co_manager_get_diag(const co_manager *m, co_mgr_diag *out);
/* Node 1..127, NULL otherwise. */
const co_mgr_node_diag *co_manager_node_diag(const co_manager *m, uint8_t node_id);
/* Zero counters, EMCY histories and the first error (not the states). */
void co_manager_reset_counters(co_manager *m);

/* Add 1F80h (U32 rw, default f80), 1F81h, 1F84h..1F88h (ARRAY 127 of
 * U32 rw, 0), 1F89h (U32 rw, 0), 1F82h (ARRAY 128 of U8 rw), 1F25h (ARRAY
 * 128 of U32 wo), 1029h and 1016h (127 entries) unless present. */
int co_od_add_manager_defaults(co_od *od, uint32_t f80);

#endif /* COGW_CORE_MANAGER_H */
