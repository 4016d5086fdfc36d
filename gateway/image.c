/* SPDX-License-Identifier: MIT */
/*
 * gateway/image.c - shared process image and forwarding lists (image.h).
 *
 * Why one atomic word per object rather than a seqlock: PDO-mappable
 * B-objects are at most 8 bytes, so the whole value fits one 64-bit atomic;
 * a store is one instruction on 64-bit targets and a lock-free
 * ldrexd/strexd or cmpxchg8b loop on 32-bit ones. Readers never retry and
 * writers never wait for each other, which a seqlock cannot offer when two
 * lines publish the same object.
 */
#include "gateway/image.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "core/pdo.h"

_Static_assert(ATOMIC_LLONG_LOCK_FREE == 2, "the process image needs lock-free 64-bit atomics");

struct gw_image {
	size_t n, cap;
	bool sealed;
	gw_image_slot *slots;
};

int gw_image_create(gw_image **out, size_t max_slots)
{
	gw_image *img;

	if (max_slots == 0 || max_slots > GW_IMAGE_MAX_SLOTS)
		return -EINVAL;
	img = calloc(1, sizeof(*img));
	if (!img)
		return -ENOMEM;
	img->slots = calloc(max_slots, sizeof(img->slots[0]));
	if (!img->slots) {
		free(img);
		return -ENOMEM;
	}
	img->cap = max_slots;
	*out = img;
	return 0;
}

void gw_image_destroy(gw_image *img)
{
	if (!img)
		return;
	free(img->slots);
	free(img);
}

static int slot_cmp(const void *a, const void *b)
{
	const gw_image_slot *x = a, *y = b;
	uint32_t kx = (uint32_t)x->index << 8 | x->sub;
	uint32_t ky = (uint32_t)y->index << 8 | y->sub;

	return kx < ky ? -1 : kx > ky;
}

int gw_image_add(gw_image *img, uint16_t index, uint8_t sub, uint8_t size, uint64_t initial)
{
	gw_image_slot *s;

	if (img->sealed)
		return -EPERM;
	if (!gw_image_in_range(index) || size < 1 || size > 8)
		return -EINVAL;
	for (size_t i = 0; i < img->n; i++)
		if (img->slots[i].index == index && img->slots[i].sub == sub)
			return -EEXIST;
	if (img->n == img->cap)
		return -ENOSPC;
	s = &img->slots[img->n++];
	s->index = index;
	s->sub = sub;
	s->size = size;
	if (size < 8)
		initial &= (UINT64_C(1) << (8 * size)) - 1;
	atomic_init(&s->value, initial);
	atomic_init(&s->writes, 0);
	return 0;
}

void gw_image_seal(gw_image *img)
{
	/* Before any thread reads: plain qsort of the atomics is fine here
	 * (values are moved bytewise while nobody else can see them). */
	qsort(img->slots, img->n, sizeof(img->slots[0]), slot_cmp);
	img->sealed = true;
}

size_t gw_image_count(const gw_image *img)
{
	return img ? img->n : 0;
}

int gw_image_find(const gw_image *img, uint16_t index, uint8_t sub)
{
	size_t lo = 0, hi;
	uint32_t key = (uint32_t)index << 8 | sub;

	if (!img || !img->sealed)
		return -ENOENT;
	hi = img->n;
	while (lo < hi) {
		size_t mid = lo + (hi - lo) / 2;
		uint32_t k = (uint32_t)img->slots[mid].index << 8 | img->slots[mid].sub;
		if (k == key)
			return (int)mid;
		if (k < key)
			lo = mid + 1;
		else
			hi = mid;
	}
	return -ENOENT;
}

const gw_image_slot *gw_image_slot_at(const gw_image *img, int slot)
{
	if (!img || slot < 0 || (size_t)slot >= img->n)
		return NULL;
	return &img->slots[slot];
}

void gw_image_write(gw_image *img, int slot, uint64_t bits)
{
	gw_image_slot *s = &img->slots[slot];

	atomic_store_explicit(&s->value, bits, memory_order_release);
	atomic_fetch_add_explicit(&s->writes, 1, memory_order_relaxed);
}

uint64_t gw_image_read(const gw_image *img, int slot)
{
	return atomic_load_explicit(&((gw_image *)img)->slots[slot].value, memory_order_acquire);
}

uint64_t gw_image_bits_from(const uint8_t *p, uint8_t size)
{
	return co_get_le(p, size);
}

void gw_image_bits_to(uint64_t bits, uint8_t *p, uint8_t size)
{
	co_put_le(p, size, bits);
}

/* ---- forwarding lists --------------------------------------------------- */

int gw_fwd_list_init(gw_fwd_list *l, const gw_image *img)
{
	size_t n = gw_image_count(img);

	memset(l, 0, sizeof(*l));
	l->words = (n + 63) / 64;
	if (l->words == 0)
		l->words = 1;
	l->bits = calloc(l->words, sizeof(l->bits[0]));
	l->scratch = calloc(l->words, sizeof(l->scratch[0]));
	l->pinned = calloc(l->words, sizeof(l->pinned[0]));
	if (!l->bits || !l->scratch || !l->pinned) {
		gw_fwd_list_fini(l);
		return -ENOMEM;
	}
	for (size_t i = 0; i < l->words; i++)
		atomic_init(&l->bits[i], 0);
	return 0;
}

void gw_fwd_list_fini(gw_fwd_list *l)
{
	free(l->bits);
	free(l->scratch);
	free(l->pinned);
	l->bits = NULL;
	l->scratch = NULL;
	l->pinned = NULL;
	l->words = 0;
}

/* Mark the slots mapped by TPDO n (0-based) in words[]. */
static unsigned mark_tpdo(const gw_image *img, const co_od *od, unsigned n, uint64_t *words)
{
	uint16_t comm = (uint16_t)(CO_PDO_TPDO_COMM + n);
	uint16_t map = (uint16_t)(CO_PDO_TPDO_MAP + n);
	uint32_t cob, entry;
	uint8_t count;
	unsigned marked = 0;

	if (co_od_get_u32(od, comm, 1, &cob) != 0 || (cob & CO_PDO_COB_INVALID))
		return 0;
	if (co_od_get_u8(od, map, 0, &count) != 0)
		return 0;
	for (uint8_t i = 1; i <= count && i <= CO_PDO_MAX_MAP; i++) {
		int slot;
		if (co_od_get_u32(od, map, i, &entry) != 0)
			continue;
		slot = gw_image_find(img, (uint16_t)(entry >> 16), (uint8_t)(entry >> 8));
		if (slot < 0)
			continue;
		if (!(words[slot / 64] & (UINT64_C(1) << (slot % 64))))
			marked++;
		words[slot / 64] |= UINT64_C(1) << (slot % 64);
	}
	return marked;
}

int gw_fwd_list_rebuild(gw_fwd_list *l, const gw_image *img, const co_od *od)
{
	uint64_t *words = l->scratch;
	unsigned total = 0;

	if (!words)
		return -EINVAL;
	memcpy(words, l->pinned, l->words * sizeof(*words));
	for (size_t i = 0; i < l->words; i++)
		total += (unsigned)__builtin_popcountll(words[i]);
	for (unsigned n = 0; n < CO_PDO_MAX; n++) {
		if (!co_od_has_index(od, (uint16_t)(CO_PDO_TPDO_COMM + n)))
			continue;
		total += mark_tpdo(img, od, n, words);
	}
	/* Word by word: a reader on another line may see a list half old and
	 * half new for an instant, which costs at most one forwarded update
	 * around the very moment of a remap. */
	for (size_t i = 0; i < l->words; i++)
		atomic_store_explicit(&l->bits[i], words[i], memory_order_release);
	l->rebuilds++;
	l->slots = total;
	return (int)total;
}

void gw_fwd_list_pin(gw_fwd_list *l, int slot)
{
	if (l->pinned && slot >= 0 && (size_t)slot / 64 < l->words)
		l->pinned[slot / 64] |= UINT64_C(1) << (slot % 64);
}

bool gw_fwd_list_has(const gw_fwd_list *l, int slot)
{
	if (!l->bits || slot < 0 || (size_t)slot / 64 >= l->words)
		return false;
	return (atomic_load_explicit(&l->bits[slot / 64], memory_order_acquire) >> (slot % 64)) &
	       1u;
}
