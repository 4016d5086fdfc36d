/* SPDX-License-Identifier: MIT */
/*
 * gateway/pdo_sync.c - lost PDO-forwarding updates (see pdo_sync.h).
 */
#include "gateway/pdo_sync.h"

#include <errno.h>
#include <stdlib.h>

#define BIT(slot) ((uint64_t)1 << ((unsigned)(slot) % 64u))

int gw_pdo_sync_init(gw_pdo_sync *s, size_t slots)
{
	s->words = (slots + 63) / 64;
	s->resync = calloc(s->words ? s->words : 1, sizeof(*s->resync));
	s->ahead = calloc(s->words ? s->words : 1, sizeof(*s->ahead));
	if (!s->resync || !s->ahead) {
		gw_pdo_sync_fini(s);
		return -ENOMEM;
	}
	return 0;
}

void gw_pdo_sync_fini(gw_pdo_sync *s)
{
	free((void *)s->resync);
	free(s->ahead);
	s->resync = NULL;
	s->ahead = NULL;
	s->words = 0;
}

void gw_pdo_sync_mark(gw_pdo_sync *s, int slot)
{
	atomic_fetch_or_explicit(&s->resync[slot / 64], BIT(slot), memory_order_release);
}

/* Without a resync before, the message is the newest this line can know
 * of and nothing more happens (no extra apply, no extra TPDO). */
void gw_pdo_sync_received(gw_pdo_sync *s, const gw_image *img, int slot, uint64_t bits)
{
	if (slot < 0 || (size_t)slot >= gw_image_count(img) || !(s->ahead[slot / 64] & BIT(slot)))
		return;
	if (gw_image_read(img, slot) == bits)
		s->ahead[slot / 64] &= ~BIT(slot); /* caught up */
	else
		gw_pdo_sync_mark(s, slot);
}

void gw_pdo_sync_take(gw_pdo_sync *s, const gw_image *img, gw_pdo_sync_apply_fn apply, void *ctx)
{
	for (size_t w = 0; w < s->words; w++) {
		uint64_t bits;

		if (!atomic_load_explicit(&s->resync[w], memory_order_relaxed))
			continue;
		bits = atomic_exchange_explicit(&s->resync[w], 0, memory_order_acquire);
		while (bits) {
			int slot = (int)(w * 64 + (size_t)__builtin_ctzll(bits));

			bits &= bits - 1;
			if (apply(ctx, slot, gw_image_read(img, slot)))
				s->ahead[w] |= BIT(slot);
		}
	}
}
