/* SPDX-License-Identifier: MIT */
/*
 * core/pdo.h - process data objects (CiA 301 §7.2.2), RPDO and TPDO.
 *
 * Which PDOs exist
 * - RPDO n (1..512) exists if 1400h+n-1 (communication) is in the OD at
 *   node creation; its mapping is 1600h+n-1 (missing = nothing mapped).
 *   TPDO n likewise with 1800h / 1A00h. co_od_add_pdo() builds the records.
 *   All per-PDO state is allocated at init; nothing is allocated later.
 * - Every PDO takes one receiver from the node's pool (co_node_config.rx_max)
 *   at init (RPDO: data, TPDO: RTR); node creation fails with -ENOSPC if the
 *   pool is too small, never at run time.
 *
 * Communication record (14xxh/18xxh)
 *   sub 1 COB-ID  bit 31 = PDO invalid, bit 30 = no RTR (TPDO), bit 29 =
 *                 29-bit CAN-ID. Bits 0..29 can change only while bit 31 is
 *                 set (0x06090030, CiA 301 §7.5.2.35); restricted CAN-IDs
 *                 (CiA 301 §7.3.5) are refused when the PDO is made valid.
 *   sub 2 transmission type (enum co_pdo_tt). 241..251 are reserved and
 *                 refused (0x06090030), so are 252/253 for an RPDO.
 *   sub 3 inhibit time, 100 µs (TPDO; only while invalid, else 0x06090030)
 *   sub 5 event timer, ms: TPDO with TT 254/255 = periodic transmission,
 *                 restarted by every transmission; RPDO = receive deadline
 *                 (armed by the first frame after the PDO became valid or
 *                 the node OPERATIONAL, CiA 301 §7.5.2.35), restarted by
 *                 every accepted frame, CO_EV_RPDO_TIMEOUT when it runs out.
 *   sub 6 SYNC start value (TPDO TT 1..240; only while invalid)
 *
 * Mapping record (16xxh/1Axxh): sub 0 = number of entries (0..64),
 * sub n = index << 16 | sub << 8 | length in bits. Dynamic remapping
 * follows CiA 301 §7.5.2.36: invalidate the COB-ID, sub 0 = 0, write the
 * entries, sub 0 = n, validate the COB-ID. Aborts:
 *   - sub 0 written while the PDO is valid, or an entry written while
 *     sub 0 != 0: CO_PDO_AB_SEQUENCE (0x06040043). CiA 301 names no code for
 *     these sequence errors (only for the value checks below); 0x06040043
 *     "general parameter incompatibility" is what CiA 301 uses for
 *     "parameter valid on its own but not now"; one constant to change.
 *   - an entry naming a missing object: 0x06020000 / 0x06090011;
 *     an object that cannot be mapped (no CO_ACC_RPDO / CO_ACC_TPDO flag,
 *     DOMAIN, length longer than the object or not a byte multiple for a
 *     string, a dummy index in a TPDO): 0x06040041;
 *   - sub 0 = n with more than 64 bits in total: 0x06040042; an entry in
 *     1..n that is 0 or invalid: 0x06040041.
 * Bit-sized and odd-length entries are packed LSB first in mapping order
 * (a BOOLEAN may be mapped with 1 bit, a UNSIGNED32 with 24, ...). An RPDO
 * writes the received bits zero-extended (sign-extended for INTEGERxx)
 * into the whole object. Dummy entries (index 0001h..0007h, RPDO only)
 * skip bits. Mappings are compiled into (entry pointer, bit offset, length)
 * when they become valid; frames never look anything up.
 *
 * Transmission (only in NMT OPERATIONAL; nothing is sent, received,
 * timed or queued in any other state, and entering OPERATIONAL starts
 * every PDO afresh):
 *   TT 0        TPDO sent at the next SYNC if co_pdo_tpdo_event() or
 *               co_pdo_object_changed() was called since the last one.
 *   TT 1..240   TPDO sent every n-th SYNC. With a start value s (sub 6) and
 *               a SYNC counter (1019h > 0) the first one goes out at the SYNC
 *               whose counter equals s, then every n-th.
 *   TT 252      TPDO sampled at every SYNC, sent on RTR.
 *   TT 253      TPDO sampled and sent on RTR.
 *   TT 254/255  TPDO sent on an event (co_pdo_tpdo_event(),
 *               co_pdo_object_changed()) or when the event timer runs out,
 *               never twice within the inhibit time: an event inside the
 *               inhibit time is remembered and sent when it elapses.
 *   RPDO TT 0..240: the data is written to the OD at the next SYNC (the
 *               latest frame wins); RPDO TT 254/255: written at once.
 *   RTR         A TPDO with bit 30 = 0 answers an RTR on its COB-ID (TT 252
 *               with the data sampled at the last SYNC, else with fresh
 *               data); with bit 30 = 1 the RTR is ignored.
 *   RPDO supervision (CiA 301 §7.5.2.35, §7.5.2.36), per RPDO, in episodes:
 *               an episode begins with the first faulty frame (or the
 *               deadline running out) and raises its EMCY once
 *               (manufacturer bytes 0..1 = RPDO number, LE, 2..4 = 0;
 *               error register bit 4, communication); it ends when a
 *               frame of the mapped length is used, which clears the
 *               code (co_emcy_clear: error-reset EMCY 0000h once no error
 *               is left) and emits CO_EV_RPDO_RECOVERED.
 *               - shorter than mapped: not processed, EMCY 8210h;
 *               - longer than mapped: the leading bytes the mapping covers
 *                 are used, EMCY 8220h (a short frame ends a "long"
 *                 episode and the other way round);
 *               - deadline missed: EMCY 8250h; a frame that is used (of
 *                 the mapped length or longer) ends this episode.
 *               CO_EV_RPDO_TIMEOUT / CO_EV_RPDO_LENGTH are emitted when an
 *               episode begins (u.pdo.fault says which), every faulty
 *               frame is counted (rx_length). A PDO made invalid and a
 *               reset communication end its episodes. Episodes stay open
 *               across NMT state changes.
 *   OD writes   RPDO values go through co_od_write() with origin
 *               CO_OD_ORIGIN_PDO: limits and check_write hooks apply (a
 *               refused value leaves that object unchanged; the event says
 *               why), after_write hooks run. Then one CO_EV_RPDO_OBJECT per
 *               mapped object and one CO_EV_RPDO with the raw bytes.
 *   TPDO read   Before sampling, a mapped object's read hook (if any) runs
 *               with origin CO_OD_ORIGIN_PDO so it can refresh the value;
 *               an abort from it is ignored (the current value is sent).
 *
 * Timers: per-PDO deadlines in a binary min-heap (see pdo.c).
 * All functions: owning thread only; return 0 or a negative errno.
 */
#ifndef COGW_CORE_PDO_H
#define COGW_CORE_PDO_H

#include <stdbool.h>
#include <stdint.h>

#include "core/co.h"
#include "core/sdo.h"

#define CO_PDO_MAX 512u     /* per direction */
#define CO_PDO_MAX_MAP 64u  /* entries per mapping */
#define CO_PDO_MAX_BITS 64u /* classic CAN: 8 bytes */

#define CO_PDO_RPDO_COMM 0x1400u
#define CO_PDO_RPDO_MAP 0x1600u
#define CO_PDO_TPDO_COMM 0x1800u
#define CO_PDO_TPDO_MAP 0x1A00u

#define CO_PDO_COB_INVALID 0x80000000u /* bit 31 */
#define CO_PDO_COB_NO_RTR 0x40000000u  /* bit 30 */
#define CO_PDO_COB_EXT CO_COB_EXT      /* bit 29 */

/* Default COB-IDs of the predefined connection set (CiA 301 §7.3.5). */
#define CO_PDO_TPDO_DEFAULT_COB(n, id) (0x80u + 0x100u * (n) + (id))
#define CO_PDO_RPDO_DEFAULT_COB(n, id) (0x100u + 0x100u * (n) + (id))

/* Mapping sequence error, see the file comment. */
#define CO_PDO_AB_SEQUENCE SDO_AB_PARAM_INCOMPAT

/* Mapping entry value. */
#define CO_PDO_MAP(index, sub, bits) \
	(((uint32_t)(index) << 16) | ((uint32_t)(sub) << 8) | (uint32_t)(bits))

typedef enum co_pdo_dir {
	CO_PDO_RX = 0, /* RPDO */
	CO_PDO_TX = 1, /* TPDO */
} co_pdo_dir;

/* Transmission types (comm sub 2). */
typedef enum co_pdo_tt {
	CO_PDO_TT_SYNC_ACYCLIC = 0,
	CO_PDO_TT_SYNC_MIN = 1,
	CO_PDO_TT_SYNC_MAX = 240,
	CO_PDO_TT_RTR_SYNC = 252,
	CO_PDO_TT_RTR_EVENT = 253,
	CO_PDO_TT_EVENT_MANUF = 254,
	CO_PDO_TT_EVENT_PROFILE = 255,
} co_pdo_tt;

/* "sync-acyclic", "sync-cyclic", "reserved", "rtr-sync", "rtr-event",
 * "event-manufacturer", "event-profile". */
const char *co_pdo_tt_to_string(uint8_t tt);
const char *co_pdo_dir_to_string(co_pdo_dir d); /* "rpdo", "tpdo" */

typedef struct co_pdo_stats {
	uint64_t rx;           /* RPDO frames accepted */
	uint64_t rx_ignored;   /* RPDO/RTR frames outside OPERATIONAL */
	uint64_t rx_length;    /* RPDO frames of the wrong length */
	uint64_t rx_late;      /* sync RPDO after the SYNC window: dropped */
	uint64_t od_refused;   /* mapped value refused by the OD (limits,
	                        * check_write hook) */
	uint64_t rx_timeout;   /* RPDO deadlines missed */
	uint64_t tx;           /* TPDO frames sent */
	uint64_t tx_failed;    /* send callback failed */
	uint64_t tx_inhibited; /* events deferred by the inhibit time */
	uint64_t tx_by_peer;   /* transmissions another sender made for us
	                        * (co_pdo_tpdo_sent_by_peer) */
	uint64_t rtr;          /* RTRs answered */
	uint64_t map_errors;   /* invalid mapping found in the OD at init or
	                        * reset (PDO left without mapping) */
} co_pdo_stats;

extern const co_service co_svc_pdo;

/*
 * Request transmission of TPDO nr (1-based) now, CiA "PDO request":
 * TT 254/255 send at once (or when the inhibit time elapses), TT 0 at the
 * next SYNC. Returns 0, -EINVAL (nr out of 1..512), -ENOENT (no such
 * TPDO), -EPERM (TT 1..240, 252, 253: those are sent by SYNC / RTR), -EAGAIN
 * (not OPERATIONAL, or the PDO is not valid).
 */
int co_pdo_tpdo_event(co_node *node, uint16_t nr, uint64_t now_us);

/*
 * The application (or the gateway) changed object index:sub. Every valid
 * TPDO mapping it is triggered: TT 254/255 sent (respecting the inhibit
 * time), TT 0 marked for the next SYNC; others are unaffected. Returns the
 * number of TPDOs triggered (0 when not OPERATIONAL). O(log n + k) through a
 * sorted (object -> TPDO) index rebuilt only when a mapping changes.
 */
int co_pdo_object_changed(co_node *node, uint16_t index, uint8_t sub, uint64_t now_us);

/* Ask the producer of RPDO nr for its data: an RTR frame with the mapped
 * length on the RPDO's COB-ID. -ENOENT, -EAGAIN (not OPERATIONAL/valid). */
int co_pdo_rpdo_request(co_node *node, uint16_t nr, uint64_t now_us);

/* Number of PDOs that exist, and whether one is valid (COB-ID bit 31
 * clear and mapping compiled). */
uint16_t co_pdo_count(const co_node *node, co_pdo_dir dir);
bool co_pdo_is_valid(const co_node *node, co_pdo_dir dir, uint16_t nr);
/* Mapped length in bytes; -ENOENT if the PDO does not exist. */
int co_pdo_length(const co_node *node, co_pdo_dir dir, uint16_t nr);
const co_pdo_stats *co_pdo_get_stats(const co_node *node);

/* ---- a second sender of the same TPDOs ------------------------------------
 *
 * The gateway's forwarding fast path (docs/gateway.md, "One wake-up per
 * hop") lets the thread of another line transmit some event-driven TPDOs
 * of this node on its behalf. Both senders must respect one inhibit time
 * (CiA 301 §7.2.2.5), so with a gate installed the core asks it before
 * every transmission, with one of these operations:
 *   CO_PDO_GATE_CLAIM  an event wants to send TPDO nr at now_us. The gate
 *                      answers CO_PDO_GATE_GO (send; the gate is taken for
 *                      this transmission), CO_PDO_GATE_SERVED (the other
 *                      sender already transmitted what this event asks
 *                      for: nothing is sent), or the time before which the
 *                      TPDO may not go (the other sender transmitted it
 *                      within the inhibit time: the event waits, exactly
 *                      like an event inside the node's own inhibit time).
 *   CO_PDO_GATE_FORCED a transmission that cannot wait (an RTR answer, a
 *                      SYNC transmission) happens now: recorded, the
 *                      answer is ignored.
 *   CO_PDO_GATE_WAIT   an event waits for the node's own inhibit time
 *                      (or, answered CO_PDO_GATE_SERVED, is dropped: the
 *                      other sender's transmission that started that
 *                      inhibit time carried it).
 *   CO_PDO_GATE_RESET  TPDO nr starts afresh (its configuration changed, the
 *                      node entered or left OPERATIONAL, a reset
 *                      communication): what the other sender knew of it
 *                      no longer holds.
 * The gate runs on the owning thread, inside the core's call: it must not
 * call back into the node.
 */
#define CO_PDO_GATE_GO 0u
#define CO_PDO_GATE_SERVED UINT64_MAX

typedef enum co_pdo_gate_op {
	CO_PDO_GATE_CLAIM = 0,
	CO_PDO_GATE_FORCED,
	CO_PDO_GATE_WAIT,
	CO_PDO_GATE_RESET,
} co_pdo_gate_op;

typedef uint64_t (*co_pdo_tx_gate_fn)(void *ctx, uint16_t nr, co_pdo_gate_op op, uint64_t now_us);

/* Install (fn NULL: remove) the gate of every TPDO of node. */
void co_pdo_set_tx_gate(co_node *node, co_pdo_tx_gate_fn fn, void *ctx);

/* The other sender transmitted TPDO nr at at_us (a time of the node's
 * clock, <= now): the inhibit time and the event timer run from then, as
 * after a transmission of the node's own. An event waiting for the inhibit
 * time keeps waiting. -ENOENT, -EAGAIN (not OPERATIONAL / not valid). */
int co_pdo_tpdo_sent_by_peer(co_node *node, uint16_t nr, uint64_t at_us);

/* What another sender needs to know of one TPDO to build its frame and
 * respect its timing (read by the owning thread, which publishes it). */
typedef struct co_pdo_tpdo_state {
	bool valid;
	bool operational;   /* the node is OPERATIONAL: PDOs may be sent */
	bool event_pending; /* an event waits for the inhibit time */
	uint8_t tt;
	uint8_t len;            /* bytes */
	uint16_t inhibit_100us; /* in force */
	uint16_t event_ms;
	uint32_t cob_id;        /* 1800h+nr-1:1 in force */
	uint64_t inhibit_until; /* no transmission before this time */
} co_pdo_tpdo_state;

/* 0, or -ENOENT if TPDO nr does not exist. */
int co_pdo_tpdo_state_get(const co_node *node, uint16_t nr, co_pdo_tpdo_state *out);

/* Supervision state of one RPDO (see "RPDO supervision" above). */
typedef struct co_pdo_rpdo_state {
	bool valid;
	uint8_t faults;     /* CO_PDO_FAULT_* episodes under way (core/event.h) */
	uint8_t mapped_len; /* bytes */
	uint16_t event_ms;  /* deadline, 0 = none */
	uint32_t cob_id;    /* 1400h+nr-1:1 in force */
} co_pdo_rpdo_state;

/* 0, or -ENOENT if RPDO nr does not exist. */
int co_pdo_rpdo_state_get(const co_node *node, uint16_t nr, co_pdo_rpdo_state *out);

/* A SYNC with this counter (0 = none) happened; the PDO service's SYNC
 * observer (core/sync.h, registered at init) calls it. */
void co_pdo_sync_ind(co_node *node, uint8_t counter, uint64_t now_us);

/* ---- building the OD ------------------------------------------------------ */

typedef struct co_pdo_desc {
	co_pdo_dir dir;
	uint16_t nr;            /* 1..512 */
	uint32_t cob_id;        /* sub 1 default */
	uint8_t tt;             /* sub 2 default */
	uint16_t inhibit_100us; /* sub 3 default */
	uint16_t event_ms;      /* sub 5 default */
	uint8_t sync_start;     /* sub 6 default (TPDO only) */
	uint8_t map_subs;       /* mapping entries to create (0 = 8, max 64) */
	uint8_t n_map;          /* mapping sub 0 default */
	const uint32_t *map;    /* n_map default entries (may be NULL if 0) */
} co_pdo_desc;

/*
 * Add the communication and mapping records of one PDO: comm sub 0 (U8 ro,
 * 5 for an RPDO, 6 for a TPDO), subs 1 (U32), 2 (U8), 3 (U16), 5 (U16),
 * 6 (U8, TPDO only), all rw; mapping sub 0 (U8 rw) and subs 1..map_subs
 * (U32 rw). -EEXIST if either record exists, -EINVAL, -ENOMEM.
 */
int co_od_add_pdo(co_od *od, const co_pdo_desc *d);

#endif /* COGW_CORE_PDO_H */
