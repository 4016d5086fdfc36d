/* SPDX-License-Identifier: MIT */
/*
 * gateway/lend.c - the lending board of a line (lend.h): 128-bit sets as
 * two atomic words, a unit taken by a compare-and-swap that clears (a
 * channel) or sets (a node) its bit.
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

/* Set n's bit if it was clear: true when this call set it. */
static bool claim_set(_Atomic uint64_t set[2], uint8_t n)
{
	return !(atomic_fetch_or_explicit(word_of(set, n), bit_of(n), memory_order_acq_rel) &
		 bit_of(n));
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

static void put_clear(_Atomic uint64_t set[2], uint8_t n)
{
	atomic_fetch_and_explicit(word_of(set, n), ~bit_of(n), memory_order_release);
}

void gw_lend_init(gw_lend *b)
{
	atomic_init(&b->carries, false);
	for (unsigned w = 0; w < 2; w++) {
		atomic_init(&b->silent[w], 0);
		atomic_init(&b->free_ch[w], 0);
		atomic_init(&b->held_node[w], 0);
	}
	for (unsigned ch = 0; ch < GW_LEND_CHANNELS; ch++)
		atomic_init(&b->handover[ch], 0);
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
		return claim_set(b->held_node, arg);
	case SDO_CLIENT_GATE_FREE_SERVER:
		put_clear(b->held_node, arg);
		return true;
	}
	return false;
}

void gw_lend_node_free(gw_lend *b, uint8_t node)
{
	put_clear(b->held_node, node);
}

bool gw_lend_claim_node(gw_lend *b, uint8_t node)
{
	return claim_set(b->held_node, node);
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

uint32_t gw_lend_reserve(gw_lend *b, uint8_t node, uint8_t *channel)
{
	uint32_t refuse;

	if (!atomic_load_explicit(&b->carries, memory_order_acquire) || gw_lend_is_silent(b, node))
		return GW_AB_NO_ANSWER; /* known silent: refuse now, not by a timeout */
	if (!claim_set(b->held_node, node))
		return sdo_abort_of_errno(-EALREADY);
	if ((refuse = reserve_channel(b, channel)))
		put_clear(b->held_node, node);
	return refuse;
}

void gw_lend_give_back(gw_lend *b, uint8_t channel, uint8_t node)
{
	if (channel != GW_LEND_NONE)
		put_set(b->free_ch, channel);
	if (node)
		put_clear(b->held_node, node);
}

/* A handover word: who offered which lease, and the node it was taken for. */
#define HO_OFFERED 0x80000000u
#define HO_TAKEN 0x40000000u

static uint32_t offer_word(uint8_t from, uint8_t node)
{
	return HO_OFFERED | (uint32_t)from << 8 | node;
}

static uint32_t taken_word(uint8_t from, uint8_t node, uint8_t new_node)
{
	return HO_TAKEN | (uint32_t)new_node << 16 | (uint32_t)from << 8 | node;
}

static bool handover_swap(gw_lend *b, uint8_t ch, uint32_t expect, uint32_t to)
{
	return ch < GW_LEND_CHANNELS &&
	       atomic_compare_exchange_strong_explicit(&b->handover[ch], &expect, to,
						       memory_order_acq_rel, memory_order_acquire);
}

void gw_lend_offer(gw_lend *b, uint8_t ch, uint8_t from, uint8_t node)
{
	if (ch < GW_LEND_CHANNELS)
		atomic_store_explicit(&b->handover[ch], offer_word(from, node),
				      memory_order_release);
}

void gw_lend_withdraw(gw_lend *b, uint8_t ch, uint8_t from, uint8_t node)
{
	handover_swap(b, ch, offer_word(from, node), 0);
}

bool gw_lend_take_offer(gw_lend *b, uint8_t ch, uint8_t from, uint8_t node, uint8_t new_node)
{
	return handover_swap(b, ch, offer_word(from, node), taken_word(from, node, new_node));
}

bool gw_lend_untake(gw_lend *b, uint8_t ch, uint8_t from, uint8_t node, uint8_t new_node)
{
	return handover_swap(b, ch, taken_word(from, node, new_node), offer_word(from, node));
}

uint8_t gw_lend_close(gw_lend *b, uint8_t ch, uint8_t from, uint8_t node)
{
	uint32_t w;

	if (ch >= GW_LEND_CHANNELS)
		return 0;
	w = atomic_exchange_explicit(&b->handover[ch], 0, memory_order_acq_rel);
	if (!(w & HO_TAKEN) || (w & 0xFFFFu) != ((uint32_t)from << 8 | node))
		return 0; /* offered, or a word of another lease of ch */
	return (uint8_t)((w >> 16) & 0x7Fu);
}
