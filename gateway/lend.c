/* SPDX-License-Identifier: MIT */
/*
 * gateway/lend.c - the lending board of a line (lend.h): the free channels
 * a 128-bit set in two atomic words (a channel taken by clearing its bit),
 * the nodes a word each (taken by a compare-and-swap from free to held).
 */
#include "gateway/lend.h"

#include <errno.h>

#include "gateway/convention.h"

static _Atomic uint64_t *word_of(_Atomic uint64_t set[2], uint8_t n)
{
	return &set[(n / 64u) & 1u];
}

static uint64_t bit_of(uint8_t n)
{
	return 1ull << (n % 64u);
}

/* Clear n's bit if it was set: true when this call cleared it. */
static bool claim_clear(_Atomic uint64_t set[2], uint8_t n)
{
	return atomic_fetch_and_explicit(word_of(set, n), ~bit_of(n), memory_order_acq_rel) &
	       bit_of(n);
}

static void put_set(_Atomic uint64_t set[2], uint8_t n)
{
	atomic_fetch_or_explicit(word_of(set, n), bit_of(n), memory_order_release);
}

/* A node's word: 0 free; NODE_HELD; or a lease that ended well, offered
 * by line `offerer` (its channel ch), or taken by line `taker`'s next
 * transfer to new_node. */
#define NODE_HELD 0x80000000u
#define NODE_OFFERED 0x40000000u
#define NODE_TAKEN 0xC0000000u
#define NODE_STATE 0xC0000000u

static uint32_t offered(uint8_t offerer, uint8_t ch)
{
	return NODE_OFFERED | (uint32_t)(offerer & 0xFu) << 26 | (uint32_t)(ch & 0x7Fu) << 15;
}

static uint32_t taken(uint8_t offerer, uint8_t ch, uint8_t new_node, uint8_t taker)
{
	return NODE_TAKEN | (uint32_t)(offerer & 0xFu) << 26 | (uint32_t)(taker & 0xFu) << 22 |
	       (uint32_t)(ch & 0x7Fu) << 15 | (new_node & 0x7Fu);
}

static uint8_t offerer_of(uint32_t w)
{
	return (uint8_t)((w >> 26) & 0xFu);
}

static uint8_t taker_of(uint32_t w)
{
	return (uint8_t)((w >> 22) & 0xFu);
}

static uint8_t channel_of(uint32_t w)
{
	return (uint8_t)((w >> 15) & 0x7Fu);
}

static uint8_t next_of(uint32_t w)
{
	return (uint8_t)(w & 0x7Fu);
}

/* w is line `from`'s lease on channel ch, taken by a next transfer. */
static bool taken_from(uint32_t w, uint8_t from, uint8_t ch)
{
	return (w & NODE_STATE) == NODE_TAKEN && offerer_of(w) == from && channel_of(w) == ch;
}

static _Atomic uint32_t *node_word(gw_lend *b, uint8_t node)
{
	return &b->node[node & 0x7Fu];
}

static bool node_swap(gw_lend *b, uint8_t node, uint32_t expect, uint32_t to)
{
	return atomic_compare_exchange_strong_explicit(node_word(b, node), &expect, to,
						       memory_order_acq_rel, memory_order_acquire);
}

static void node_put(gw_lend *b, uint8_t node, uint32_t v)
{
	atomic_store_explicit(node_word(b, node), v, memory_order_release);
}

void gw_lend_init(gw_lend *b)
{
	atomic_init(&b->carries, false);
	for (unsigned w = 0; w < 2; w++) {
		atomic_init(&b->silent[w], 0);
		atomic_init(&b->free_ch[w], 0);
	}
	for (unsigned n = 0; n < 128; n++)
		atomic_init(&b->node[n], 0);
}

void gw_lend_set_carries(gw_lend *b, bool carries)
{
	atomic_store_explicit(&b->carries, carries, memory_order_release);
}

void gw_lend_set_silent(gw_lend *b, const uint64_t lost[2])
{
	for (unsigned w = 0; w < 2; w++)
		if (atomic_load_explicit(&b->silent[w], memory_order_relaxed) != lost[w])
			atomic_store_explicit(&b->silent[w], lost[w], memory_order_release);
}

bool gw_lend_is_silent(const gw_lend *b, uint8_t node)
{
	return atomic_load_explicit(&b->silent[(node / 64u) & 1u], memory_order_acquire) &
	       bit_of(node);
}

bool gw_lend_gate(void *ctx, sdo_client_gate_op op, uint8_t arg)
{
	gw_lend *b = ctx;

	switch (op) {
	case SDO_CLIENT_GATE_TAKE_CHANNEL:
		return claim_clear(b->free_ch, arg);
	case SDO_CLIENT_GATE_FREE_CHANNEL:
		put_set(b->free_ch, arg);
		return true;
	case SDO_CLIENT_GATE_TAKE_SERVER:
		return gw_lend_claim_node(b, arg);
	case SDO_CLIENT_GATE_FREE_SERVER:
		node_put(b, arg, 0);
		return true;
	}
	return false;
}

void gw_lend_node_free(gw_lend *b, uint8_t node)
{
	node_put(b, node, 0);
}

bool gw_lend_claim_node(gw_lend *b, uint8_t node)
{
	return node_swap(b, node, 0, NODE_HELD);
}

uint8_t gw_lend_hand_over(gw_lend *b, uint8_t from, uint8_t node, uint8_t ch, uint8_t *taker)
{
	for (;;) {
		uint32_t w = atomic_load_explicit(node_word(b, node), memory_order_acquire);

		if (!taken_from(w, from, ch))
			return 0;
		/* its line may still make it an offer again (gw_lend_untake):
		 * hence the swap */
		if (node_swap(b, node, w, next_of(w) == node ? NODE_HELD : 0)) {
			*taker = taker_of(w);
			return next_of(w);
		}
	}
}

uint8_t gw_lend_end_offered(gw_lend *b, uint8_t from, uint8_t node, uint8_t ch, uint8_t *taker)
{
	for (;;) {
		uint32_t w = atomic_load_explicit(node_word(b, node), memory_order_acquire);
		uint8_t next;

		if (w == offered(from, ch)) {
			if (node_swap(b, node, w, 0))
				return 0; /* nobody took it: freed with the offer */
		} else if (taken_from(w, from, ch)) {
			if ((next = gw_lend_hand_over(b, from, node, ch, taker)))
				return next; /* else made an offer again meanwhile */
		} else {
			node_put(b, node, 0); /* not offered by this lease */
			return 0;
		}
	}
}

bool gw_lend_claim_channel(gw_lend *b, uint8_t ch)
{
	return claim_clear(b->free_ch, ch);
}

static uint32_t reserve_channel(gw_lend *b, uint8_t *channel)
{
	for (unsigned w = 0; w < 2; w++) {
		uint64_t v = atomic_load_explicit(&b->free_ch[w], memory_order_acquire);
		while (v) {
			uint64_t lowest = v & -v;
			if (atomic_compare_exchange_weak_explicit(&b->free_ch[w], &v, v & ~lowest,
								  memory_order_acq_rel,
								  memory_order_acquire)) {
				*channel = (uint8_t)(w * 64u + (unsigned)__builtin_ctzll(lowest));
				return 0;
			}
		}
	}
	return GW_AB_NO_CLIENT;
}

uint32_t gw_lend_reserve(gw_lend *b, uint8_t from, uint8_t node, uint8_t *channel, bool *taken_over)
{
	uint32_t refuse, w;

	*taken_over = false;
	if (!atomic_load_explicit(&b->carries, memory_order_acquire) || gw_lend_is_silent(b, node))
		return GW_AB_NO_ANSWER; /* known silent: refuse now, not by a timeout */
	w = atomic_load_explicit(node_word(b, node), memory_order_acquire);
	if ((w & NODE_STATE) == NODE_OFFERED &&
	    node_swap(b, node, w, taken(offerer_of(w), channel_of(w), node, from))) {
		/* a lease toward it that ended well (ours, or another line's
		 * whose M_CLOSE may still be on its way): the node and its
		 * channel at once, the owner not having ended it */
		*channel = channel_of(w);
		*taken_over = true;
		return 0;
	}
	if (!gw_lend_claim_node(b, node))
		return sdo_abort_of_errno(-EALREADY);
	if ((refuse = reserve_channel(b, channel)))
		node_put(b, node, 0);
	return refuse;
}

void gw_lend_give_back(gw_lend *b, uint8_t channel, uint8_t node)
{
	if (channel != GW_LEND_NONE)
		put_set(b->free_ch, channel);
	if (node)
		node_put(b, node, 0);
}

void gw_lend_offer(gw_lend *b, uint8_t from, uint8_t node, uint8_t ch)
{
	node_swap(b, node, NODE_HELD, offered(from, ch));
}

void gw_lend_withdraw(gw_lend *b, uint8_t from, uint8_t node, uint8_t ch)
{
	node_swap(b, node, offered(from, ch), NODE_HELD);
}

bool gw_lend_take_offer(gw_lend *b, uint8_t from, uint8_t node, uint8_t ch, uint8_t new_node)
{
	return node_swap(b, node, offered(from, ch), taken(from, ch, new_node, from));
}

bool gw_lend_untake(gw_lend *b, uint8_t from, uint8_t node, uint8_t ch, uint8_t new_node)
{
	uint32_t w = atomic_load_explicit(node_word(b, node), memory_order_acquire);

	return (w & NODE_STATE) == NODE_TAKEN && taker_of(w) == from && channel_of(w) == ch &&
	       next_of(w) == new_node && node_swap(b, node, w, offered(offerer_of(w), ch));
}
