/* SPDX-License-Identifier: MIT */
/*
 * gateway/pdo_sync.h - lost PDO-forwarding updates, per target line.
 *
 * An update of a B-object travels to each line whose TPDOs map it as a
 * ring message carrying its value. When that ring is full the update is
 * dropped (and counted by the caller), and the slot is marked here instead:
 * the target's next wake-up applies the image's latest value, so the last
 * value always arrives. That resync may overtake messages still queued with
 * older values; the line then remembers it is "ahead", and when such an
 * older message has been applied while the image holds another value, the
 * slot is marked again so the newest value comes back before the line
 * sleeps.
 *
 * Threads: gw_pdo_sync_mark from any line; the rest only by the line that
 * owns the gw_pdo_sync.
 */
#ifndef COGW_GATEWAY_PDO_SYNC_H
#define COGW_GATEWAY_PDO_SYNC_H

#include <stdatomic.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "gateway/image.h"

typedef struct gw_pdo_sync {
	_Atomic uint64_t *resync; /* slots to apply from the image (set by any line) */
	uint64_t *ahead;          /* slots a resync moved past queued messages (owner only) */
	size_t words;
} gw_pdo_sync;

/* Stores the value of slot's image in the owner line's copy; returns
 * whether it stored one (false: already held, or refused). */
typedef bool (*gw_pdo_sync_apply_fn)(void *ctx, int slot, uint64_t bits);

int gw_pdo_sync_init(gw_pdo_sync *s, size_t slots);
void gw_pdo_sync_fini(gw_pdo_sync *s);

/* An update of slot could not be handed to the owner: any thread. */
void gw_pdo_sync_mark(gw_pdo_sync *s, int slot);

/* The owner applied a queued message of slot carrying bits. */
void gw_pdo_sync_received(gw_pdo_sync *s, const gw_image *img, int slot, uint64_t bits);

/* The owner, after draining its rings: apply the image's value of every
 * marked slot through apply. */
void gw_pdo_sync_take(gw_pdo_sync *s, const gw_image *img, gw_pdo_sync_apply_fn apply, void *ctx);

#endif /* COGW_GATEWAY_PDO_SYNC_H */
