/* SPDX-License-Identifier: MIT */
/*
 * gateway/image.h - the shared process image B000h..BFFFh and the
 * per-line forwarding lists of PDO forwarding.
 *
 * The image is defined once for all lines at start-up (one slot per
 * B-object, numeric, 1..8 bytes) and never changes shape afterwards.
 * Each line keeps owning its own OD: an RPDO on line A that writes a
 * B-object publishes the value into its slot, and line B, told by a
 * message, copies it into its own OD entry and triggers its TPDOs.
 *
 * No torn values: a slot's value is one _Atomic uint64_t (the little-
 * endian bit pattern of the object), so a reader on any thread sees either
 * the old or the new value of an 8-byte object, never half of each. Lock-
 * free on every platform cogw builds for (checked at compile time), so no
 * lock is taken on the real-time path and several writers are harmless
 * (the last one wins).
 *
 * Threads: create/add/seal/destroy on the main thread before the lines
 * start; gw_image_read/write/find from any thread afterwards.
 * A forwarding list belongs to one line: that line rebuilds it (after its
 * TPDO mapping changed); any line may ask gw_fwd_list_has().
 */
#ifndef COGW_GATEWAY_IMAGE_H
#define COGW_GATEWAY_IMAGE_H

#include <stdatomic.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "core/od.h"

#define GW_IMAGE_MAX_SLOTS 4096u

typedef struct gw_image_slot {
	uint16_t index;
	uint8_t sub;
	uint8_t size;            /* bytes, 1..8 */
	_Atomic uint64_t value;  /* little-endian bit pattern */
	_Atomic uint64_t writes; /* publications so far */
} gw_image_slot;

typedef struct gw_image gw_image;

static inline bool gw_image_in_range(uint16_t index)
{
	return index >= 0xB000u && index <= 0xBFFFu;
}

int gw_image_create(gw_image **out, size_t max_slots);
void gw_image_destroy(gw_image *img); /* accepts NULL */
/* Define a slot. -EINVAL (index outside B000h..BFFFh, size not 1..8),
 * -EEXIST, -ENOSPC, -EPERM (already sealed). */
int gw_image_add(gw_image *img, uint16_t index, uint8_t sub, uint8_t size, uint64_t initial);
/* Freeze the shape (sorts the slots). Lookups need a sealed image. */
void gw_image_seal(gw_image *img);
size_t gw_image_count(const gw_image *img);
/* Slot number of (index, sub), or -ENOENT. O(log n). */
int gw_image_find(const gw_image *img, uint16_t index, uint8_t sub);
const gw_image_slot *gw_image_slot_at(const gw_image *img, int slot);

void gw_image_write(gw_image *img, int slot, uint64_t bits);
uint64_t gw_image_read(const gw_image *img, int slot);

/* Wire bytes <-> bit pattern of size bytes (little-endian). */
uint64_t gw_image_bits_from(const uint8_t *p, uint8_t size);
void gw_image_bits_to(uint64_t bits, uint8_t *p, uint8_t size);

/* ---- forwarding lists --------------------------------------------------- */

typedef struct gw_fwd_list {
	size_t words;
	_Atomic uint64_t *bits; /* bit s: slot s is mapped into a valid TPDO */
	uint64_t *scratch;      /* rebuild area, allocated at init */
	uint64_t *pinned;       /* slots always in the list (gw_fwd_list_pin) */
	uint32_t rebuilds;
	uint32_t slots; /* slots in the list after the last rebuild */
} gw_fwd_list;

int gw_fwd_list_init(gw_fwd_list *l, const gw_image *img);
void gw_fwd_list_fini(gw_fwd_list *l);
/* Rebuild from the TPDOs in od: every slot mapped by a TPDO whose COB-ID
 * (1800h+n sub 1) has bit 31 clear and whose mapping (1A00h+n) has
 * entries. Returns the number of slots in the list. */
int gw_fwd_list_rebuild(gw_fwd_list *l, const gw_image *img, const co_od *od);
bool gw_fwd_list_has(const gw_fwd_list *l, int slot);
/* Keep slot in the list whatever the TPDOs map (from the next rebuild). */
void gw_fwd_list_pin(gw_fwd_list *l, int slot);

#endif /* COGW_GATEWAY_IMAGE_H */
