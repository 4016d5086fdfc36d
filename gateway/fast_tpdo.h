/* SPDX-License-Identifier: MIT */
/*
 * gateway/fast_tpdo.h - PDO forwarding in one wake-up: the event-driven
 * TPDOs of a line that the thread of another line may transmit itself,
 * in the wake-up in which it received the forwarded value
 * (docs/gateway.md, "One wake-up per hop").
 *
 * The line that owns the TPDOs (the target) publishes, per fast TPDO, what
 * a frame needs (COB-ID, length, the image slots it maps and their bit
 * lengths, the inhibit time) and a gate; a source line that wrote a mapped
 * B-object builds the frame from the shared image and sends it on its own
 * socket bound to the target's interface, if it can take the gate. The
 * target's core asks the same gate before each of its own transmissions
 * (core/pdo.h co_pdo_set_tx_gate), so the two senders share one inhibit
 * time, and learns of the source's transmission by the ring message that
 * carries the value (co_pdo_tpdo_sent_by_peer).
 *
 * The gate, one 64-bit atomic word per fast TPDO:
 *   bit 63       CLOSED: sources must hand the update off (the TPDO is
 *                being republished, or cannot be sent by another thread)
 *   bits 56..62  generation, +1 at every republication
 *   bits 0..55   the earliest time (µs, CLOCK_MONOTONIC, the line loops'
 *                clock) at which the next transmission may start
 * Every transmission, by either side, is a compare-and-swap of that word
 * from a value whose time has passed to (same generation, now + inhibit):
 * of two senders only one wins, the other waits (target) or hands off
 * (source).
 *
 * The busy word, one 32-bit atomic per fast TPDO: the number of updates
 * handed off toward it that the target has not applied yet, or whose frame
 * still waits in its transmit queue (a source counts one before pushing,
 * the target takes it off after applying, or once its queue is empty),
 * plus FAST_PENDING while the target's core holds an event waiting for the
 * inhibit time. A source sends only while it is 0: a frame of it must not
 * overtake a value of its own still queued, nor come between a waiting
 * event and its transmission. (gateway/gw_pdo.c adds the same rule for all
 * of a source's messages: the target must have done them all, but for
 * quiet ones sent under the same publication, see below.)
 *
 * Quiet updates: when every TPDO of the owner that maps a slot is a fast
 * one (the quiet set) and the source sent them all, the owner has nothing
 * to do for the update but note it: the source hands it off without waking
 * the owner (lines/xring.h xring_push_quiet), which applies it at its next
 * wake-up before anything else (line_ext before_events). The owner's OD
 * then lags the bus while it sleeps; it sends nothing from the lagging OD
 * because every way it could (the update itself, an inhibit time's end, a
 * reconfiguration) either applies the quiet updates first or goes through
 * a publication, whose epoch a source compares with the one its unapplied
 * quiet updates were sent under before it sends again.
 *
 * Republication (owner): gate to CLOSED with the next generation, release
 * fence, descriptor words (relaxed atomics), gate open with the time of
 * the last transmission. A source reads the descriptor between its load of
 * the gate and its compare-and-swap, with an acquire fence before the
 * latter (a seqlock's reader): if it read anything of a republication, its
 * swap fails.
 *
 * Threads: gw_fast_try/hold/release from any source line; everything else
 * (init, fini, publish, close, gate, taken, carrying) on the owner line
 * (init/fini: before the lines start / after they stopped).
 */
#ifndef COGW_GATEWAY_FAST_TPDO_H
#define COGW_GATEWAY_FAST_TPDO_H

#include <stdatomic.h>
#include <stdbool.h>
#include <stdint.h>

#include "core/frame.h"
#include "core/pdo.h"
#include "gateway/image.h"

#define GW_FAST_MAX 32u    /* fast TPDOs per line */
#define GW_FAST_NONE 0xFFu /* gw_fast.of_nr: not a fast TPDO */
#define GW_FAST_GATE_CLOSED (UINT64_C(1) << 63)
#define GW_FAST_PENDING 0x80000000u
#define GW_FAST_SENT_MAX 4u      /* fast TPDOs a source sends for one update */
#define GW_FAST_MAP_BITS 0x7Fu   /* gw_fast_desc.map: the entry's length */
#define GW_FAST_MAP_SIGNED 0x80u /* gw_fast_desc.map: fits as a signed integer */

/* What a source needs to build the frame of one TPDO. */
typedef struct gw_fast_desc {
	uint16_t nr;
	uint32_t can_id;
	uint8_t flags; /* co_frame flags */
	uint8_t len;
	uint8_t n;
	/* each value must fit its bits (as a signed integer where its entry
	 * has GW_FAST_MAP_SIGNED, else as an unsigned one), or the frame is
	 * left to the owner, who refuses it: a device object's frame
	 * (lines/line_ext.h line_tpdo_sources) */
	uint8_t fit;
	uint32_t inhibit_us;
	uint32_t map[CO_PDO_MAX_MAP]; /* image slot << 8 | bits (and flags), in mapping order */
} gw_fast_desc;

typedef struct gw_fast_tpdo {
	_Atomic uint64_t gate;
	_Atomic uint32_t busy;
	_Atomic uint16_t nr;
	_Atomic uint32_t can_id;
	_Atomic uint8_t flags, len, n, fit;
	_Atomic uint32_t inhibit_us;
	_Atomic uint32_t map[CO_PDO_MAX_MAP];
} gw_fast_tpdo;

typedef struct gw_fast {
	size_t n_slots;
	_Atomic uint32_t *by_slot; /* per image slot: the fast TPDOs mapping it (bit k) */
	_Atomic bool carrying;     /* the owner line takes frames at once now */
	/* per image slot (bit slot % 64 of word slot / 64): every TPDO of the
	 * owner that maps it is a fast one, and nothing else on the owner
	 * acts on its updates, so an update whose TPDOs all left from the
	 * source may wait for the owner's next wake-up (gw_fast_quiet_ok) */
	_Atomic uint64_t *quiet;
	/* +1 whenever what is published changes (after it changed): a source
	 * holding updates the owner has not applied yet compares it with the
	 * one they were sent under (gw_fast_epoch) */
	_Atomic uint32_t epoch;
	gw_fast_tpdo t[GW_FAST_MAX];
	/* owner only */
	uint16_t nr[GW_FAST_MAX]; /* 0 = free */
	uint8_t of_nr[CO_PDO_MAX];
	/* the TPDOs a source sent for the update being applied */
	const uint16_t *serving_nr;
	unsigned n_serving;
	size_t quiet_words;
	/* the caller's build area for publish: the quiet set, and the slots
	 * a TPDO that is not fast maps (which keeps them out of it) */
	uint64_t *quiet_next, *mapped_slow;
	uint64_t *sourced; /* slots of fast TPDOs built from named sources */
	bool stale;        /* a TPDO was reset: publish again before sleeping */
	/* held updates applied while the owner's transmit queue was not
	 * empty: their frames may still be queued, so they count as busy
	 * until it is (gw_fast_set_carrying) */
	uint32_t deferred[GW_FAST_MAX];
	uint32_t *scratch;
	gw_fast_desc cur[GW_FAST_MAX];  /* what is published */
	gw_fast_desc next[GW_FAST_MAX]; /* the caller's build area for publish */
} gw_fast;

/* Sends one frame on the target's interface from the source thread. */
typedef int (*gw_fast_send_fn)(void *ctx, const co_frame *f);

int gw_fast_init(gw_fast *F, size_t n_slots);
void gw_fast_fini(gw_fast *F);

/* ---- owner ---------------------------------------------------------------- */

/* Make the set of fast TPDOs exactly descs[0..n): each one published with
 * its last transmission's inhibit end (inhibit_until[i]) and whether an
 * event waits (pending[i]); the others closed; and the quiet set exactly
 * `quiet` (gw_fast.quiet, quiet_words words; NULL: empty). Slots leave the
 * quiet set before the TPDOs change and join it after, so a source never
 * finds a slot quiet that the TPDOs it reads do not make quiet. Returns
 * how many were published (n, or fewer when more than GW_FAST_MAX). */
unsigned gw_fast_publish(gw_fast *F, const gw_fast_desc *descs, const uint64_t *inhibit_until,
			 const bool *pending, unsigned n, const uint64_t *quiet);
void gw_fast_set_carrying(gw_fast *F, bool carrying);
/* The core's gate (co_pdo_tx_gate_fn with ctx = F). A reset of a TPDO
 * closes its gate at once and marks F stale: the owner publishes again
 * (gw_fast_publish clears it) before its loop sleeps. */
uint64_t gw_fast_gate(void *ctx, uint16_t nr, co_pdo_gate_op op, uint64_t now_us);
/* The owner applied an update handed off with these held TPDOs; tx_idle:
 * nothing waits in its transmit queue (else they stay busy until
 * gw_fast_set_carrying(F, true): a source's frame must not overtake the
 * frame this update queued). */
void gw_fast_taken(gw_fast *F, uint32_t held, bool tx_idle);
/* TPDO number of fast TPDO k, 0 if none. */
uint16_t gw_fast_nr(const gw_fast *F, unsigned k);

/* ---- source --------------------------------------------------------------- */

/* Slot's value changed in img (already written there): send every fast
 * TPDO of F that maps it and may go now through send, at most
 * GW_FAST_SENT_MAX. Returns the mask of those sent, their TPDO numbers in
 * sent_nr[0..popcount); *held gets the mask of those that must learn of
 * the update by hand-off before a later one may be sent (count them with
 * gw_fast_hold before pushing the message, undo with gw_fast_taken if the
 * push fails). */
uint32_t gw_fast_try(gw_fast *F, const gw_image *img, int slot, uint64_t now_us,
		     gw_fast_send_fn send, void *send_ctx, uint32_t *held,
		     uint16_t sent_nr[GW_FAST_SENT_MAX]);
/* What is published now; read before gw_fast_try and gw_fast_quiet_ok
 * (acquire: what they read is at least that new). */
uint32_t gw_fast_epoch(const gw_fast *F);
/* slot is in the quiet set (gw_fast.quiet). */
bool gw_fast_quiet_ok(const gw_fast *F, int slot);
void gw_fast_hold(gw_fast *F, uint32_t held);
/* The hand-off failed (ring full or closed): what gw_fast_hold counted. */
void gw_fast_undo_hold(gw_fast *F, uint32_t held);
/* The fast TPDOs that map slot: what an update handed off without trying
 * holds. */
uint32_t gw_fast_tpdos_of(gw_fast *F, int slot);

#endif /* COGW_GATEWAY_FAST_TPDO_H */
