/* SPDX-License-Identifier: MIT */
/*
 * core/manager_int.h - what the files of the CiA 302-2 manager share (the
 * public API is core/manager.h). Include it from core/manager*.c only.
 *
 * The files, each one thing:
 *   manager.c           life cycle (create, destroy) and time (tick)
 *   manager_entry.c     the way in (mgr_enter/mgr_after around every entry
 *                       point) and NMT commands out
 *   manager_boot.c      the boot slave process of one node (a machine)
 *   manager_net.c       the network machine of the line
 *   manager_supervise.c inputs from the core: boot-ups, error control,
 *                       EMCY, frames on the manager's own node-ID, NMT
 *   manager_request.c   the application's requests (core/manager.h)
 *   manager_diag.c      names, events, flags, diagnostics and counters
 *   manager_od.c        the manager's objects: 1F82h, 1F25h, the lock of
 *                       1F80h..1F89h during the boot
 *
 * Together they are the CiA 302-2 manager of one line: NMT start-up
 * (1F80h), the network boot, one boot slave process per node (1F81h,
 * 1F84h..1F89h), error control supervision, Request NMT (1F82h),
 * configuration request (1F25h) and the diagnostics of the line.
 *
 * Why the boot runs in parallel: booted one after another (node 1, then
 * node 2, ...), a silent node would cost every node behind it one SDO
 * timeout. Here every assigned node runs its own machine and only the SDO
 * client pool bounds how many talk at once (a node holds one "boot slot"
 * from its 1000h read to the end of the configure step; there are as many
 * slots as client channels, so the pool's FIFO never overflows because of
 * the boot); the PDO layout step after it holds the slot too.
 *
 * A boot that restarts while its SDO request runs does not cancel it: it
 * disowns it (the confirmation is ignored). The pool runs requests to one
 * server in submission order, so the next request of that node starts
 * only after the old answer or timeout; a cancel would leave the old
 * answer on the bus to be taken for the answer of the next request.
 *
 * Re-entrancy: the core delivers events synchronously, and the manager's
 * own calls (SDO cancel, NMT send) may produce events. Every entry point
 * therefore only feeds inputs to machines; the work that looks at the
 * whole line (waking nodes that wait for a channel, the network start
 * decision, state/flag reports) runs once at the end of the outermost
 * entry (mgr_after), never from inside a machine handler.
 */
#ifndef COGW_CORE_MANAGER_INT_H
#define COGW_CORE_MANAGER_INT_H

#include <stdbool.h>
#include <stdint.h>

#include "core/co_internal.h"
#include "core/fsm.h"
#include "core/manager.h"
#include "core/od.h"
#include "core/sdo.h"

#define MGR_TAG 0x4D47520000000000ull /* "MGR" in the top bytes */
#define MGR_TAG_MASK 0xFFFFFF0000000000ull
#define STATE_UNKNOWN 0xFFu

/* ---- the machines' states and inputs, the manager and its slaves ---------- */

enum bs_state {
	BS_IDLE = 0,     /* not booting */
	BS_ASSIGNMENT,   /* 302-2 boot slave: "slave in network list (1F81h)?" */
	BS_KEEP_ALIVE,   /* 302-2: keep-alive bit set -> NMT state check */
	BS_WAIT_BOOTUP,  /* 302-2 network boot: after reset communication */
	BS_WAIT_CHANNEL, /* waits for a boot slot (SDO client pool) */
	BS_DEVICE_TYPE,  /* 302-2: "check device type" 1000h vs 1F84h */
	BS_IDENTITY,     /* 302-2: "check identification" 1018h:1..4 vs
	                  * 1F85h..1F88h */
	BS_CONFIGURE,    /* 302-2: "check and update configuration" (302-3) */
	BS_ERRCTRL,      /* 302-2: "start error control service" */
	BS_START,        /* 302-2: "start slave" per 1F80h */
	BS_BOOTED,       /* 302-2: boot slave process finished, supervised */
	BS_FAILED,       /* 302-2: error status A..O; retry per retry_ms */
	BS_SOFTWARE,     /* 302-2: "check software" (302-3 software manager),
	                  * between BS_IDENTITY and BS_CONFIGURE */
	BS_PDO_LAYOUT,   /* the slave's PDO layout (core/pdo_scan.h), between
	                  * BS_CONFIGURE and BS_ERRCTRL */
	BS_COUNT
};

enum in_kind {
	IN_SDO,
	IN_BOOTUP,
	IN_HB,
	IN_CHANNEL,
	IN_CONFIGURED,
	IN_SOFTWARE,
	IN_PDO_LAYOUT
};

struct mgr_in {
	enum in_kind kind;
	uint32_t abort;
	uint32_t value;
	uint16_t index;
	uint8_t sub;
	uint32_t found; /* IN_SOFTWARE: the value read at index:sub */
	bool guarded;   /* IN_HB: seen through node guarding */
};

/* Inputs of the network machine (co_fsm_con). */
enum net_in_kind {
	NET_IN_CHECK,              /* after every input: can the boot end, the
	                            * network start? (mgr_after) */
	NET_IN_OWN_ID_CONFLICT,    /* another device on our node-ID: FATAL */
	NET_IN_RESET_ALL_ON_ERROR, /* a mandatory slave lost error control,
	                            * 1F80h bit 4: the network boots again */
	NET_IN_STOP_ALL_ON_ERROR   /* ... 1F80h bit 6: the network stops */
};

struct mgr_net_in {
	enum net_in_kind kind;
};

struct mgr_slave {
	co_manager *m;
	uint8_t id;
	co_fsm fsm;
	uint64_t timer_us;
	bool slot; /* holds a boot slot */
	bool sdo_pending;
	uint64_t tag; /* of the pending SDO request */
	uint32_t gen; /* bumps when a pending request is disowned */
	uint8_t buf[4];
	uint8_t id_sub;    /* 1018h sub being checked (1..4) */
	bool network_boot; /* this boot is part of the network boot */
	bool wait_bootup;  /* reset communication was sent: wait */
	bool already_op;   /* keep-alive node found OPERATIONAL (L) */
	bool attempted;    /* a boot attempt ended since the network boot */
	bool ever_booted;  /* booted since the network boot began */
	bool keep_op;
	uint8_t target_state; /* NMT state after its boot (CO_NMT_OPERATIONAL,
	                       * PRE_OPERATIONAL or STOPPED) */
	bool boot_deferred;   /* boot-up while the network was stopped: booted
	                       * when the network leaves STOPPED */
	bool lost;            /* error control lost after boot */
	bool unexpected_reported;
	bool dup_reported;
	bool mismatch;         /* identity wrong (C, D, M, N, O) */
	bool cmd_since_bootup; /* the manager sent it an NMT command */
	bool emcy_active;
	uint8_t last_state;      /* NMT state last heard (HB, guarding, boot-up) */
	uint8_t expected_state;  /* last state the manager commanded */
	uint64_t bootup_us;      /* last boot-up heard (0 = none) */
	bool bootup_since_reset; /* a boot-up came after our last reset */
	char last_fail;          /* letter of the last reported failure */
	uint8_t last_fail_step;
	uint32_t last_fail_abort;
	co_mgr_node_diag d;
};

struct co_manager {
	co_node *node;
	co_od *od;
	co_manager_config cfg;
	co_fsm fsm;
	uint8_t own_id;
	uint8_t reset_cs;         /* NMT command of the next network reset */
	uint64_t timer_us;        /* end of the boot time, 1F89h */
	uint64_t boot_started_us; /* the network boot began (1F89h counts) */
	uint64_t scan_us;         /* next scan for missing nodes */
	bool autostart_pending;
	bool boot_time_expired;
	bool awaiting_mandatory; /* BOOTED because 1F89h ran out */
	bool net_started;
	bool net_started_explicit;
	bool start_requested; /* a start from STOPPED waits for mandatory slaves */
	/* FATAL because of a node-ID conflict: left by itself when its
	 * episode ends (manager_supervise.c) */
	bool fatal_by_conflict;
	uint8_t own_id_frame_reported; /* bit per kind: heartbeat, EMCY, SDO */
	bool wake_pending;
	bool check_pending;
	int depth;
	uint8_t reported_state, reported_flags;
	bool reported_once;
	int rx[3];
	uint8_t n_slots, slots_used;
	bool destroying;
	co_mgr_diag cnt;         /* counters and first error (bit lists unused) */
	struct mgr_slave s[128]; /* by node-ID, [0] unused */
};

/* The two machines (manager_boot.c, manager_net.c). */
extern const co_fsm_def mgr_boot_def;
extern const co_fsm_def mgr_net_def;

/* ---- OD access, machine states ------------------------------------------------ */

static inline uint32_t od_u32(const co_manager *m, uint16_t index, uint8_t sub)
{
	uint32_t v = 0;
	(void)co_od_get_u32(m->od, index, sub, &v);
	return v;
}

static inline uint32_t f80(const co_manager *m)
{
	return od_u32(m, 0x1F80, 0);
}

static inline uint32_t assignment(const co_manager *m, uint8_t id)
{
	return id >= 1 && id <= 127 ? od_u32(m, 0x1F81, id) : 0;
}

static inline bool is_slave(const co_manager *m, uint8_t id)
{
	return assignment(m, id) & CO_MGR_1F81_SLAVE;
}

static inline bool is_mandatory(const co_manager *m, uint8_t id)
{
	uint32_t a = assignment(m, id);
	return (a & CO_MGR_1F81_SLAVE) && (a & CO_MGR_1F81_MANDATORY);
}

/* Nodes the manager boots: assigned as slave with "may be booted". */
static inline bool is_bootable(const co_manager *m, uint8_t id)
{
	uint32_t a = assignment(m, id);
	return (a & CO_MGR_1F81_SLAVE) && (a & CO_MGR_1F81_BOOT);
}

/* Heartbeat consumer time for `id` from 1016h (0 = not monitored). */
static inline uint16_t hb_time_ms(const co_manager *m, uint8_t id)
{
	uint8_t n = 0;
	if (co_od_get_u8(m->od, 0x1016, 0, &n) < 0)
		return 0;
	for (uint8_t sub = 1; sub && sub <= n; sub++) {
		uint32_t v = od_u32(m, 0x1016, sub);
		if (((v >> 16) & 0xFF) == id && (v & 0xFFFF))
			return (uint16_t)(v & 0xFFFF);
	}
	return 0;
}

static inline bool is_master(const co_manager *m)
{
	return f80(m) & CO_MGR_1F80_MASTER;
}

static inline int bs_state(const struct mgr_slave *s)
{
	return co_fsm_state_of(&s->fsm);
}

static inline bool bs_running(const struct mgr_slave *s)
{
	int st = bs_state(s);
	return st != BS_IDLE && st != BS_BOOTED && st != BS_FAILED;
}

static inline void bs_input(struct mgr_slave *s, const struct mgr_in *in, uint64_t now_us)
{
	co_fsm_con(&s->fsm, in, now_us);
}

static inline bool mgr_active(const co_manager *m)
{
	uint8_t st = (uint8_t)co_fsm_state_of(&m->fsm);
	return st != CO_MGR_SLAVE && st != CO_MGR_FATAL;
}

/* ---- manager_entry.c ------------------------------------------------------------ */
void mgr_enter(co_manager *m, uint64_t now_us);
void mgr_after(co_manager *m, uint64_t now_us);
void mgr_nmt_send(co_manager *m, uint8_t target, uint8_t cs, uint64_t now_us);
/* Feed an input to the network machine. */
void mgr_net_input(co_manager *m, enum net_in_kind kind, uint64_t now_us);

/* ---- manager_diag.c ------------------------------------------------------------- */
void mgr_emit(co_manager *m, co_event_kind kind, const co_ev_mgr *e);
void mgr_note_first_error(co_manager *m, uint8_t id, char status, uint32_t code);
void mgr_emit_node(co_manager *m, uint8_t id, uint8_t what, uint32_t value);
void mgr_emit_boot(struct mgr_slave *s, uint8_t step, char status, uint32_t abort, uint16_t index,
		   uint8_t sub, uint32_t value, uint32_t expected, bool done);
uint8_t mgr_compute_flags(const co_manager *m);
void mgr_report_state(co_manager *m);

/* ---- manager_boot.c ------------------------------------------------------------- */
bool mgr_boot_hold_stopped(struct mgr_slave *s, uint64_t now_us);
void mgr_boot_begin(struct mgr_slave *s, bool network_boot, bool wait_bootup, uint64_t now_us);

/* ---- manager_net.c -------------------------------------------------------------- */
bool mgr_all_mandatory_booted(const co_manager *m);
int mgr_start_network_now(co_manager *m, bool explicit, uint64_t now_us);
void mgr_boot_deferred_nodes(co_manager *m, uint64_t now_us);
void mgr_start_from_stopped(co_manager *m, uint64_t now_us);

/* ---- manager_supervise.c -------------------------------------------------------- */
void mgr_own_id_rx(co_node *node, void *arg, const co_frame *f, uint64_t now_us);
bool mgr_nmt_rx_filter(void *ctx, co_node *node, uint8_t cs, uint8_t target, uint64_t now_us);
void mgr_scan(co_manager *m, uint64_t now_us);

/* ---- manager_request.c ---------------------------------------------------------- */
int mgr_cmd_to_cs(uint8_t cmd);

/* ---- manager_od.c --------------------------------------------------------------- */
/* Hook (on) or unhook the manager's objects. */
void mgr_od_hooks(co_manager *m, bool on);

#endif /* COGW_CORE_MANAGER_INT_H */
