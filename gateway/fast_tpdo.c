/* SPDX-License-Identifier: MIT */
/*
 * gateway/fast_tpdo.c - fast TPDOs of PDO forwarding (fast_tpdo.h).
 *
 * Why a gate and not a message to the target asking it to send: the
 * message is the second wake-up this path exists to save. Why a
 * compare-and-swap on one word and not a lock: a lock shared between two
 * line threads on the real-time path could make one wait for the other;
 * a failed swap only means "hand it off as before".
 */
#include "gateway/fast_tpdo.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#define GATE_TIME_MASK ((UINT64_C(1) << 56) - 1)
#define GATE_GEN_SHIFT 56
#define GATE_GEN_MASK (UINT64_C(0x7F) << GATE_GEN_SHIFT)

static uint64_t gate_time(uint64_t g)
{
	return g & GATE_TIME_MASK;
}

static uint64_t gate_with_time(uint64_t g, uint64_t t)
{
	return (g & ~GATE_TIME_MASK) | (t & GATE_TIME_MASK);
}

static uint64_t gate_next_gen(uint64_t g)
{
	return (g + (UINT64_C(1) << GATE_GEN_SHIFT)) & GATE_GEN_MASK;
}

int gw_fast_init(gw_fast *F, size_t n_slots)
{
	memset(F, 0, sizeof(*F));
	F->n_slots = n_slots;
	F->by_slot = calloc(n_slots ? n_slots : 1, sizeof(*F->by_slot));
	F->scratch = calloc(n_slots ? n_slots : 1, sizeof(*F->scratch));
	F->quiet_words = n_slots / 64 + 1;
	F->quiet = calloc(F->quiet_words, sizeof(*F->quiet));
	F->quiet_next = calloc(F->quiet_words, sizeof(*F->quiet_next));
	F->mapped_slow = calloc(F->quiet_words, sizeof(*F->mapped_slow));
	F->sourced = calloc(F->quiet_words, sizeof(*F->sourced));
	if (!F->by_slot || !F->scratch || !F->quiet || !F->quiet_next || !F->mapped_slow ||
	    !F->sourced) {
		gw_fast_fini(F);
		return -ENOMEM;
	}
	for (size_t i = 0; i < n_slots; i++)
		atomic_init(&F->by_slot[i], 0);
	for (size_t i = 0; i < F->quiet_words; i++)
		atomic_init(&F->quiet[i], 0);
	atomic_init(&F->epoch, 0);
	for (unsigned k = 0; k < GW_FAST_MAX; k++) {
		atomic_init(&F->t[k].gate, GW_FAST_GATE_CLOSED);
		atomic_init(&F->t[k].busy, 0);
		atomic_init(&F->t[k].nr, 0);
	}
	memset(F->of_nr, GW_FAST_NONE, sizeof(F->of_nr));
	atomic_init(&F->carrying, false);
	return 0;
}

void gw_fast_fini(gw_fast *F)
{
	free((void *)F->by_slot);
	free(F->scratch);
	free((void *)F->quiet);
	free(F->quiet_next);
	free(F->mapped_slow);
	free(F->sourced);
	F->quiet_next = F->mapped_slow = F->sourced = NULL;
	F->by_slot = NULL;
	F->scratch = NULL;
	F->quiet = NULL;
	F->n_slots = 0;
	F->quiet_words = 0;
}

/* ---- owner ------------------------------------------------------------------ */

static void gate_close(gw_fast_tpdo *t)
{
	atomic_fetch_or_explicit(&t->gate, GW_FAST_GATE_CLOSED, memory_order_acq_rel);
}

static void set_pending(gw_fast_tpdo *t, bool on)
{
	if (on)
		atomic_fetch_or_explicit(&t->busy, GW_FAST_PENDING, memory_order_release);
	else
		atomic_fetch_and_explicit(&t->busy, ~GW_FAST_PENDING, memory_order_release);
}

/* Close with the next generation, write the descriptor, open again. The
 * descriptor stores are releases and the source's loads acquires: a
 * source that read any word of this publication has the close before it,
 * so its compare-and-swap fails (a seqlock without fences, which
 * ThreadSanitizer can follow). */
static void publish_one(gw_fast_tpdo *t, const gw_fast_desc *d, uint64_t inhibit_until,
			bool pending)
{
	uint64_t g = atomic_load_explicit(&t->gate, memory_order_relaxed), open;

	while (!atomic_compare_exchange_weak_explicit(
		&t->gate, &g, gate_next_gen(g) | GW_FAST_GATE_CLOSED | gate_time(g),
		memory_order_acq_rel, memory_order_relaxed))
		;
	atomic_store_explicit(&t->nr, d->nr, memory_order_release);
	atomic_store_explicit(&t->can_id, d->can_id, memory_order_release);
	atomic_store_explicit(&t->flags, d->flags, memory_order_release);
	atomic_store_explicit(&t->len, d->len, memory_order_release);
	atomic_store_explicit(&t->n, d->n, memory_order_release);
	atomic_store_explicit(&t->fit, d->fit, memory_order_release);
	atomic_store_explicit(&t->inhibit_us, d->inhibit_us, memory_order_release);
	for (uint8_t i = 0; i < d->n; i++)
		atomic_store_explicit(&t->map[i], d->map[i], memory_order_release);
	set_pending(t, pending);
	/* Only the owner changes the generation and the CLOSED bit; sources
	 * only move the time, so a swap keeps whatever time they set. */
	g = atomic_load_explicit(&t->gate, memory_order_relaxed);
	do {
		uint64_t at = gate_time(g) > inhibit_until ? gate_time(g) : inhibit_until;
		open = gate_with_time(g & ~GW_FAST_GATE_CLOSED, at);
	} while (!atomic_compare_exchange_weak_explicit(&t->gate, &g, open, memory_order_release,
							memory_order_relaxed));
}

static int find_k(const gw_fast *F, uint16_t nr)
{
	return nr >= 1 && nr <= CO_PDO_MAX && F->of_nr[nr - 1] != GW_FAST_NONE ? F->of_nr[nr - 1]
									       : -1;
}

static void retire(gw_fast *F, unsigned k)
{
	gate_close(&F->t[k]);
	set_pending(&F->t[k], false);
	F->of_nr[F->nr[k] - 1] = GW_FAST_NONE;
	F->nr[k] = 0;
}

static int take_free(gw_fast *F, uint16_t nr)
{
	for (unsigned k = 0; k < GW_FAST_MAX; k++) {
		if (!F->nr[k]) {
			F->nr[k] = nr;
			F->of_nr[nr - 1] = (uint8_t)k;
			return (int)k;
		}
	}
	return -1;
}

static void next_epoch(gw_fast *F)
{
	atomic_store_explicit(&F->epoch, atomic_load_explicit(&F->epoch, memory_order_relaxed) + 1,
			      memory_order_release);
}

/* Whether anything a source reads changed. */
static bool rebuild_by_slot(gw_fast *F)
{
	bool changed = false;

	memset(F->scratch, 0, F->n_slots * sizeof(*F->scratch));
	for (unsigned k = 0; k < GW_FAST_MAX; k++) {
		if (!F->nr[k])
			continue;
		for (uint8_t i = 0; i < F->cur[k].n; i++) {
			uint32_t slot = F->cur[k].map[i] >> 8;
			if (slot < F->n_slots)
				F->scratch[slot] |= UINT32_C(1) << k;
		}
	}
	for (size_t s = 0; s < F->n_slots; s++)
		if (atomic_load_explicit(&F->by_slot[s], memory_order_relaxed) != F->scratch[s]) {
			atomic_store_explicit(&F->by_slot[s], F->scratch[s], memory_order_release);
			changed = true;
		}
	return changed;
}

/* Store quiet & keep (keep: all ones, or the slots staying quiet);
 * whether a word changed. */
static bool store_quiet(gw_fast *F, const uint64_t *quiet, bool leaving_only)
{
	bool changed = false;

	for (size_t i = 0; i < F->quiet_words; i++) {
		uint64_t old = atomic_load_explicit(&F->quiet[i], memory_order_relaxed);
		uint64_t v = quiet ? quiet[i] : 0;

		if (leaving_only)
			v &= old;
		if (v == old)
			continue;
		atomic_store_explicit(&F->quiet[i], v, memory_order_release);
		changed = true;
	}
	return changed;
}

unsigned gw_fast_publish(gw_fast *F, const gw_fast_desc *descs, const uint64_t *inhibit_until,
			 const bool *pending, unsigned n, const uint64_t *quiet)
{
	unsigned published = 0;
	bool changed = store_quiet(F, quiet, true);

	for (unsigned k = 0; k < GW_FAST_MAX; k++) {
		bool keep = false;
		for (unsigned i = 0; F->nr[k] && i < n; i++)
			keep |= descs[i].nr == F->nr[k];
		if (F->nr[k] && !keep) {
			retire(F, k);
			changed = true;
		}
	}
	for (unsigned i = 0; i < n; i++) {
		int k = find_k(F, descs[i].nr);
		if (k < 0 && (k = take_free(F, descs[i].nr)) < 0)
			continue; /* more than GW_FAST_MAX: that one keeps the hand-off */
		published++;
		/* unchanged and open: nothing to tell the sources */
		if (!(atomic_load_explicit(&F->t[k].gate, memory_order_relaxed) &
		      GW_FAST_GATE_CLOSED) &&
		    memcmp(&F->cur[k], &descs[i], sizeof(descs[i])) == 0)
			continue;
		F->cur[k] = descs[i];
		publish_one(&F->t[k], &descs[i], inhibit_until[i], pending[i]);
		changed = true;
	}
	changed |= rebuild_by_slot(F);
	changed |= store_quiet(F, quiet, false);
	/* once, after everything: a source that read any of it under the
	 * old epoch finds the epoch moved */
	if (changed)
		next_epoch(F);
	F->stale = false;
	return published;
}

void gw_fast_set_carrying(gw_fast *F, bool carrying)
{
	if (carrying) {
		for (unsigned k = 0; k < GW_FAST_MAX; k++) {
			if (!F->deferred[k])
				continue;
			atomic_fetch_sub_explicit(&F->t[k].busy, F->deferred[k],
						  memory_order_release);
			F->deferred[k] = 0;
		}
	}
	if (atomic_load_explicit(&F->carrying, memory_order_relaxed) != carrying)
		atomic_store_explicit(&F->carrying, carrying, memory_order_release);
}

uint16_t gw_fast_nr(const gw_fast *F, unsigned k)
{
	return k < GW_FAST_MAX ? F->nr[k] : 0;
}

/* Take the gate for a transmission of the owner now, or say until when
 * another sender's transmission keeps it. */
static uint64_t owner_claim(gw_fast_tpdo *t, uint64_t now_us)
{
	uint64_t g = atomic_load_explicit(&t->gate, memory_order_acquire);
	uint64_t inhibit = atomic_load_explicit(&t->inhibit_us, memory_order_relaxed);

	do {
		if (now_us < gate_time(g)) {
			set_pending(t, true);
			return gate_time(g);
		}
	} while (!atomic_compare_exchange_weak_explicit(
		&t->gate, &g, gate_with_time(g, now_us + inhibit), memory_order_acq_rel,
		memory_order_acquire));
	set_pending(t, false);
	return CO_PDO_GATE_GO;
}

static void owner_forced(gw_fast_tpdo *t, uint64_t now_us)
{
	uint64_t g = atomic_load_explicit(&t->gate, memory_order_acquire);
	uint64_t inhibit = atomic_load_explicit(&t->inhibit_us, memory_order_relaxed);
	uint64_t at = now_us + inhibit;

	while (!atomic_compare_exchange_weak_explicit(
		&t->gate, &g, gate_with_time(g, gate_time(g) > at ? gate_time(g) : at),
		memory_order_acq_rel, memory_order_acquire))
		;
	set_pending(t, false);
}

/* A source sent nr for the update being applied. By number, not by k:
 * the update may have been sent under an earlier publication. */
static bool serving(const gw_fast *F, uint16_t nr)
{
	for (unsigned i = 0; i < F->n_serving; i++)
		if (F->serving_nr[i] == nr)
			return true;
	return false;
}

uint64_t gw_fast_gate(void *ctx, uint16_t nr, co_pdo_gate_op op, uint64_t now_us)
{
	gw_fast *F = ctx;
	int k = find_k(F, nr);

	if (op == CO_PDO_GATE_RESET)
		F->stale = true; /* it may have become a fast TPDO */
	/* its frame left from the source (even if it is no fast TPDO any
	 * more); its inhibit time runs from that frame */
	if ((op == CO_PDO_GATE_CLAIM || op == CO_PDO_GATE_WAIT) && serving(F, nr))
		return CO_PDO_GATE_SERVED;
	if (k < 0)
		return CO_PDO_GATE_GO;
	switch (op) {
	case CO_PDO_GATE_CLAIM:
		return owner_claim(&F->t[k], now_us);
	case CO_PDO_GATE_FORCED:
		owner_forced(&F->t[k], now_us);
		return CO_PDO_GATE_GO;
	case CO_PDO_GATE_WAIT:
		set_pending(&F->t[k], true);
		return CO_PDO_GATE_GO;
	case CO_PDO_GATE_RESET:
		gate_close(&F->t[k]);
		F->stale = true;
		return CO_PDO_GATE_GO;
	}
	return CO_PDO_GATE_GO;
}

/* Count updates held toward the TPDOs in held (up) or take them off. */
static void busy_change(gw_fast *F, uint32_t held, bool up)
{
	while (held) {
		unsigned k = (unsigned)__builtin_ctz(held);

		held &= held - 1;
		if (up)
			atomic_fetch_add_explicit(&F->t[k].busy, 1, memory_order_acq_rel);
		else
			atomic_fetch_sub_explicit(&F->t[k].busy, 1, memory_order_release);
	}
}

void gw_fast_taken(gw_fast *F, uint32_t held, bool tx_idle)
{
	if (tx_idle) {
		busy_change(F, held, false);
		return;
	}
	for (; held; held &= held - 1)
		F->deferred[__builtin_ctz(held)]++;
}

/* ---- source ------------------------------------------------------------------ */

void gw_fast_hold(gw_fast *F, uint32_t held)
{
	busy_change(F, held, true);
}

void gw_fast_undo_hold(gw_fast *F, uint32_t held)
{
	busy_change(F, held, false);
}

/* Whether v keeps its value in bits (signed: as a two's complement
 * integer, sign-extended to 64 bits in the image). */
static bool fits(uint64_t v, unsigned bits, bool is_signed)
{
	if (bits >= 64)
		return true;
	if (is_signed) {
		int64_t s = (int64_t)v, lim = INT64_C(1) << (bits - 1);
		return s >= -lim && s < lim;
	}
	return v >> bits == 0;
}

/* The frame of t from the image's values, packed as core/pdo_map.c packs
 * a TPDO: entries LSB first in mapping order, each the low bits of its
 * object. false: a value does not fit where t asks for it (the owner
 * refuses it). */
static bool build_frame(gw_fast_tpdo *t, const gw_image *img, co_frame *f, uint32_t *inhibit_us,
			uint16_t *nr)
{
	uint8_t n = atomic_load_explicit(&t->n, memory_order_acquire);
	bool fit = atomic_load_explicit(&t->fit, memory_order_acquire);
	uint64_t acc = 0;
	unsigned off = 0;

	co_frame_init(f, atomic_load_explicit(&t->can_id, memory_order_acquire),
		      atomic_load_explicit(&t->len, memory_order_acquire));
	f->flags = atomic_load_explicit(&t->flags, memory_order_acquire);
	*inhibit_us = atomic_load_explicit(&t->inhibit_us, memory_order_acquire);
	*nr = atomic_load_explicit(&t->nr, memory_order_acquire);
	for (uint8_t i = 0; i < n && i < CO_PDO_MAX_MAP; i++) {
		uint32_t e = atomic_load_explicit(&t->map[i], memory_order_acquire);
		unsigned bits = e & GW_FAST_MAP_BITS;
		int slot = (int)(e >> 8);
		uint64_t mask = bits >= 64 ? UINT64_MAX : (UINT64_C(1) << bits) - 1;
		uint64_t v;

		if (off + bits > 64 || !gw_image_slot_at(img, slot))
			break; /* torn by a republication: the swap below fails */
		v = gw_image_read(img, slot);
		if (fit && !fits(v, bits, e & GW_FAST_MAP_SIGNED))
			return false;
		acc |= (v & mask) << off;
		off += bits;
	}
	if (f->len > 8)
		f->len = 8;
	co_put_le(f->data, f->len, acc);
	return true;
}

/* One fast TPDO: take its gate and send (its number), or leave it to the
 * hand-off (0). */
static uint16_t try_one(gw_fast_tpdo *t, const gw_image *img, uint64_t now_us, gw_fast_send_fn send,
			void *send_ctx)
{
	uint64_t g, taken;
	uint32_t inhibit_us;
	uint16_t nr;
	co_frame f;

	if (atomic_load_explicit(&t->busy, memory_order_acquire))
		return 0;
	g = atomic_load_explicit(&t->gate, memory_order_acquire);
	if ((g & GW_FAST_GATE_CLOSED) || now_us < gate_time(g))
		return 0;
	if (!build_frame(t, img, &f, &inhibit_us, &nr))
		return 0;
	taken = gate_with_time(g, now_us + inhibit_us);
	if (!atomic_compare_exchange_strong_explicit(&t->gate, &g, taken, memory_order_acq_rel,
						     memory_order_relaxed))
		return 0;
	if (send(send_ctx, &f) == 0)
		return nr;
	/* Not sent (the interface is down or congested): give the time back
	 * unless someone moved the gate meanwhile. */
	atomic_compare_exchange_strong_explicit(&t->gate, &taken, g, memory_order_acq_rel,
						memory_order_relaxed);
	return 0;
}

uint32_t gw_fast_tpdos_of(gw_fast *F, int slot)
{
	if (slot < 0 || (size_t)slot >= F->n_slots)
		return 0;
	return atomic_load_explicit(&F->by_slot[slot], memory_order_acquire);
}

uint32_t gw_fast_epoch(const gw_fast *F)
{
	return atomic_load_explicit(&F->epoch, memory_order_acquire);
}

bool gw_fast_quiet_ok(const gw_fast *F, int slot)
{
	if (slot < 0 || (size_t)slot >= F->n_slots)
		return false;
	return (atomic_load_explicit(&F->quiet[slot / 64], memory_order_acquire) >> (slot % 64)) &
	       1u;
}

uint32_t gw_fast_try(gw_fast *F, const gw_image *img, int slot, uint64_t now_us,
		     gw_fast_send_fn send, void *send_ctx, uint32_t *held,
		     uint16_t sent_nr[GW_FAST_SENT_MAX])
{
	uint32_t mask, sent = 0;
	unsigned n_sent = 0;

	*held = 0;
	if (slot < 0 || (size_t)slot >= F->n_slots)
		return 0;
	mask = atomic_load_explicit(&F->by_slot[slot], memory_order_acquire);
	if (!mask)
		return 0;
	if (!atomic_load_explicit(&F->carrying, memory_order_acquire)) {
		*held = mask;
		return 0;
	}
	for (uint32_t m = mask; m && n_sent < GW_FAST_SENT_MAX; m &= m - 1) {
		unsigned k = (unsigned)__builtin_ctz(m);
		uint16_t nr = try_one(&F->t[k], img, now_us, send, send_ctx);

		if (nr) {
			sent |= UINT32_C(1) << k;
			sent_nr[n_sent++] = nr;
		}
	}
	*held = mask & ~sent;
	return sent;
}
