/* SPDX-License-Identifier: MIT */
/*
 * lines/line_pending.c - the pending-request table of a line (see
 * line_pending.h): two free stacks and a generation per slot.
 */
#include "lines/line_pending.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#define SLOT_BITS 16u
#define SLOT_MASK ((1u << SLOT_BITS) - 1u)

int line_pending_init(line_pending_table *t, uint32_t big_cap)
{
	memset(t, 0, sizeof *t);
	t->big_bufs = malloc((size_t)big_cap * LINE_BIG_SLOTS);
	if (!t->big_bufs)
		return -ENOMEM;
	for (uint16_t i = 0; i < LINE_PENDING_MAX; i++) {
		line_pending *p = &t->slot[i];
		p->tag = i; /* generation 0 */
		if (i < LINE_BIG_SLOTS) {
			p->buf = t->big_bufs + (size_t)big_cap * i;
			p->cap = big_cap;
		} else {
			p->buf = p->inline_data;
			p->cap = LINE_INLINE_MAX;
		}
	}
	/* stacks: lowest slot on top */
	for (uint16_t i = 0; i < LINE_BIG_SLOTS; i++)
		t->free_big[t->n_free_big++] = (uint16_t)(LINE_BIG_SLOTS - 1 - i);
	for (uint16_t i = LINE_PENDING_MAX; i-- > LINE_BIG_SLOTS;)
		t->free_small[t->n_free_small++] = i;
	return 0;
}

void line_pending_fini(line_pending_table *t)
{
	free(t->big_bufs);
	t->big_bufs = NULL;
}

line_pending *line_pending_take(line_pending_table *t, const mbx_request *req,
				line_pending_kind kind, bool big)
{
	uint16_t *n_free = big ? &t->n_free_big : &t->n_free_small;
	uint16_t i;

	/* The last free slot of each kind is for writers: read-only clients
	 * parking uploads (a dead node answers nothing for the whole SDO
	 * timeout) must not make a writer's request fail with BUSY (issue
	 * 11; the mailbox limits how many requests readers park at all). */
	if (*n_free == 0 || (*n_free == 1 && req->access < MBX_ACCESS_WRITE))
		return NULL;
	i = big ? t->free_big[--*n_free] : t->free_small[--*n_free];
	line_pending *p = &t->slot[i];
	p->used = true;
	p->kind = (uint8_t)kind;
	p->code = req->code;
	p->reply = req->reply;
	/* a new generation: completions for the slot's previous use miss */
	p->tag = ((p->tag >> SLOT_BITS) + 1u) << SLOT_BITS | i;
	t->used++;
	return p;
}

line_pending *line_pending_find(line_pending_table *t, uint64_t tag)
{
	uint32_t i = (uint32_t)(tag & SLOT_MASK);

	if (i >= LINE_PENDING_MAX)
		return NULL;
	line_pending *p = &t->slot[i];
	return p->used && p->tag == tag ? p : NULL;
}

void line_pending_release(line_pending_table *t, line_pending *p)
{
	uint16_t i = (uint16_t)(p - t->slot);

	if (!p->used)
		return;
	p->used = false;
	t->used--;
	if (i < LINE_BIG_SLOTS)
		t->free_big[t->n_free_big++] = i;
	else
		t->free_small[t->n_free_small++] = i;
}
