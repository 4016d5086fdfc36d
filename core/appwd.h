/* SPDX-License-Identifier: MIT */
/*
 * core/appwd.h - the application watchdog and the safe outputs of a line
 * (docs/application.md, "The application watchdog and host ready").
 *
 * A client of the daemon that drives the outputs may declare itself
 * essential: an interval and a set of reactions. The entry is armed by its
 * first keep-alive; from then on every keep-alive moves its deadline to
 * now + interval. An armed entry whose deadline passes trips once: the
 * caller (the line thread) runs its reactions at once, from state the line
 * already holds, without the client that failed.
 *
 * The reactions (bits, equal to the wire's MBX_APPWD_R_*):
 *   EMCY            the own node's EMCY 6200h "user software", error
 *                   register 81h (generic + manufacturer): the frame
 *                   80h+id [00 62 81 00 00 00 00 00] (co_appwd_react)
 *   NMT_PREOP / NMT_STOP / NMT_RESET_COMM / NMT_RESET_NODE
 *                   that NMT command to all nodes; at most one per set.
 *                   Carried out by the line's NMT master (the CiA 302
 *                   manager), not here: co_appwd_nmt_cs() names it
 *   HB_STOP         the own heartbeat producer stops (1017h = 0)
 *   SAFE_OUTPUTS    the configured safe values written into the own
 *                   object dictionary, and every TPDO that maps one of
 *                   them sent at once (co_appwd_safe_outputs_apply)
 *
 * What a trip leaves behind (the EMCY error, the stopped heartbeat) is
 * undone by co_appwd_acknowledge(), which the line calls when a writer
 * declares again and no entry is tripped any more.
 *
 * No I/O: time comes in as a parameter. One co_appwd per line, owned by
 * the line thread.
 */
#ifndef COGW_CORE_APPWD_H
#define COGW_CORE_APPWD_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "core/co.h"

enum co_appwd_reaction {
	CO_APPWD_EMCY = 1u << 0,
	CO_APPWD_NMT_PREOP = 1u << 1,
	CO_APPWD_NMT_STOP = 1u << 2,
	CO_APPWD_NMT_RESET_COMM = 1u << 3,
	CO_APPWD_NMT_RESET_NODE = 1u << 4,
	CO_APPWD_HB_STOP = 1u << 5,
	CO_APPWD_SAFE_OUTPUTS = 1u << 6,
};
#define CO_APPWD_NMT_MASK \
	(CO_APPWD_NMT_PREOP | CO_APPWD_NMT_STOP | CO_APPWD_NMT_RESET_COMM | CO_APPWD_NMT_RESET_NODE)
#define CO_APPWD_ALL 0x7Fu

/* The EMCY of the EMCY reaction (CiA 301 table 21: 6200h user software;
 * error register bits 0 generic and 7 manufacturer). */
#define CO_APPWD_EMCY_CODE 0x6200u
#define CO_APPWD_EMCY_REG 0x81u

#define CO_APPWD_MAX 4u /* essential clients per line */
#define CO_APPWD_INTERVAL_MIN_MS 10u
#define CO_APPWD_INTERVAL_MAX_MS 60000u

/* Known bits only, not empty, at most one NMT reaction. */
bool co_appwd_reactions_valid(uint32_t reactions);
/* The NMT command specifier of the set's NMT reaction (core/nmt.h), 0 = none. */
uint8_t co_appwd_nmt_cs(uint32_t reactions);

typedef enum co_appwd_state {
	CO_APPWD_FREE = 0,
	CO_APPWD_DECLARED, /* waiting for its first keep-alive */
	CO_APPWD_ARMED,
	CO_APPWD_TRIPPED,
} co_appwd_state;

const char *co_appwd_state_to_string(co_appwd_state s); /* "declared", ... */

typedef struct co_appwd_entry {
	uint8_t state;  /* co_appwd_state */
	bool gone;      /* the owner left the mailbox (died, lease, unregistered) */
	uint32_t owner; /* the mailbox client id */
	uint32_t pid;
	uint32_t interval_ms;
	uint32_t reactions;
	uint64_t deadline_us; /* ARMED: the keep-alive deadline; TRIPPED: the missed one */
	uint64_t keepalives;
} co_appwd_entry;

typedef struct co_appwd_stats {
	uint64_t declared;        /* declarations accepted (again included) */
	uint64_t keepalives;      /* keep-alives that renewed a deadline */
	uint64_t refused;         /* declarations refused: full table, bad set */
	uint64_t trips;           /* deadlines missed */
	uint64_t late_keepalives; /* keep-alives of a tripped entry */
} co_appwd_stats;

typedef struct co_appwd {
	co_appwd_entry e[CO_APPWD_MAX];
	co_appwd_stats stats;
} co_appwd;

void co_appwd_init(co_appwd *wd);

/*
 * Declare (or declare again) the owner essential: a new declaration
 * replaces the owner's entry, waiting for its first keep-alive. interval_ms
 * 0 withdraws the owner's entry. 0, -EINVAL (bad interval or set), -ENOSPC
 * (table full), -ENOENT (withdrawing what was not declared).
 */
int co_appwd_declare(co_appwd *wd, uint32_t owner, uint32_t pid, uint32_t interval_ms,
		     uint32_t reactions);

/* A keep-alive: arms or renews. 0, -ENOENT (not declared), -ESTALE (tripped:
 * nothing renewed until the owner declares again). */
int co_appwd_keepalive(co_appwd *wd, uint32_t owner, uint64_t now_us);

/* The owner left the mailbox: an armed entry stays and trips at its
 * deadline (its process may have died: nobody else would tell); a declared
 * or tripped one is freed. */
void co_appwd_owner_gone(co_appwd *wd, uint32_t owner);

/*
 * Trip the armed entries whose deadline is at or before now: each is
 * copied to fired[] (up to cap; the rest trip at the next call) and left
 * TRIPPED (freed when its owner is gone). Returns how many tripped.
 */
size_t co_appwd_poll(co_appwd *wd, uint64_t now_us, co_appwd_entry *fired, size_t cap);

/* The earliest deadline of an armed entry, CO_NO_DEADLINE if none. */
uint64_t co_appwd_next_deadline(const co_appwd *wd);

/* Is any entry tripped now? */
bool co_appwd_any_tripped(const co_appwd *wd);

/* The owner's entry, NULL if none. */
const co_appwd_entry *co_appwd_find(const co_appwd *wd, uint32_t owner);

/* ---- reactions on the node ---------------------------------------------- */

/* One safe output: a value of the own object dictionary. */
typedef struct co_safe_output {
	uint16_t index;
	uint8_t sub;
	uint8_t len; /* 1..8 */
	uint8_t value[8];
} co_safe_output;

/*
 * Write the safe values (their checks, no check_write hook: the refusal
 * of an application that may be the one that failed must not keep the
 * outputs where they are), then send every TPDO mapping one of them
 * (event-driven at once, synchronous at the next SYNC; only in
 * OPERATIONAL). Returns how many values were written; an entry that is
 * missing or refuses its value is skipped.
 */
size_t co_appwd_safe_outputs_apply(co_node *node, const co_safe_output *outs, size_t n,
				   uint64_t now_us);

/* What co_appwd_react left behind, for co_appwd_acknowledge. */
typedef struct co_appwd_effects {
	bool emcy;            /* EMCY 6200h raised */
	bool hb_stopped;      /* 1017h set to 0 */
	uint16_t hb_saved_ms; /* 1017h before */
} co_appwd_effects;

/*
 * Run the node's own reactions of the set: SAFE_OUTPUTS first (their
 * TPDOs leave while the node still runs), then EMCY, then HB_STOP. The NMT
 * reaction is the caller's. Returns the reactions carried out.
 */
uint32_t co_appwd_react(co_node *node, uint32_t reactions, const co_safe_output *outs,
			size_t n_outs, co_appwd_effects *fx, uint64_t now_us);

/* Undo the effects: the EMCY error reset (0000h when no other error stays
 * active), the heartbeat producer's 1017h again. */
void co_appwd_acknowledge(co_node *node, co_appwd_effects *fx, uint64_t now_us);

#endif /* COGW_CORE_APPWD_H */
