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

int line_pending_init(line_pending_table *t, uint32_t big_cap, mbx_budget *budget)
{
	memset(t, 0, sizeof *t);
	for (uint16_t i = 0; i < LINE_PENDING_MAX; i++) {
		line_pending *p = &t->slot[i];
		p->tag = i; /* generation 0 */
		if (i < LINE_BIG_SLOTS) {
			p->buf = mbx_buffer_reserve(big_cap);
			if (!p->buf) {
				line_pending_fini(t);
				return -ENOMEM;
			}
			p->cap = big_cap;
			p->budget = budget;
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
	for (uint16_t i = 0; i < LINE_BIG_SLOTS; i++) {
		line_pending *p = &t->slot[i];
		mbx_buffer_free(p->buf, p->cap);
		p->buf = NULL;
	}
}

int line_pending_grow(line_pending *p, uint32_t end, uint32_t total)
{
	uint32_t want;

	if (end > p->cap)
		return -ENOMEM;
	if (end > p->touched)
		p->touched = end;
	if (end <= p->reserved)
		return 0;
	if (total != UINT32_MAX && total >= end && total <= p->cap) {
		want = total;
	} else {
		uint64_t step = ((uint64_t)end + MBX_BUFFER_KEEP - 1) / MBX_BUFFER_KEEP *
				MBX_BUFFER_KEEP;
		want = step < p->cap ? (uint32_t)step : p->cap;
	}
	if (!mbx_budget_take(p->budget, want - p->reserved, p->keep_free)) {
		p->over_budget = true;
		return -ENOMEM;
	}
	p->reserved = want;
	return 0;
}

void line_pending_pay_back(line_pending *p)
{
	mbx_budget_give(p->budget, p->reserved);
	p->reserved = 0;
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
	p->route_ext = LINE_NO_ROUTE;
	p->answer = NULL;
	p->answer_ctx = NULL;
	p->code = req->code;
	p->reply = req->reply;
	p->keep_free = req->access < MBX_ACCESS_WRITE ? p->cap : 0;
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
	line_pending_pay_back(p);
	if (p->touched > MBX_BUFFER_KEEP)
		mbx_buffer_release(p->buf, p->touched);
	p->touched = 0;
	p->over_budget = false;
	if (i < LINE_BIG_SLOTS)
		t->free_big[t->n_free_big++] = i;
	else
		t->free_small[t->n_free_small++] = i;
}
