/* SPDX-License-Identifier: MIT */
/*
 * lines/line_pending.h - the mailbox requests a line has handed to its core
 * and not yet answered (SDO transfers, LSS services).
 *
 * A fixed table allocated at line creation: LINE_PENDING_MAX slots, of
 * which the first LINE_BIG_SLOTS own a buffer of max_transfer bytes (big
 * uploads and downloads); the others carry LINE_INLINE_MAX bytes inline.
 * Taking and releasing a slot are O(1) (a free stack per kind); so is
 * finding one by its tag: the tag is the core tag of the request, built
 * from the slot number (low 16 bits) and a per-slot generation, so a late
 * completion for a slot that was released and reused never matches.
 *
 * Line thread only.
 */
#ifndef COGW_LINES_LINE_PENDING_H
#define COGW_LINES_LINE_PENDING_H

#include <stdbool.h>
#include <stdint.h>

#include "lines/line_ext.h"
#include "mailbox/server.h"

#define LINE_PENDING_MAX 64 /* mailbox requests waiting for the core */
#define LINE_BIG_SLOTS 4    /* of which with a max_transfer buffer */
#define LINE_INLINE_MAX 1024
#define LINE_NO_ROUTE 0xFFu

/* What a pending request waits for: how to cancel it. */
typedef enum line_pending_kind {
	LINE_PENDING_SDO = 1, /* SDO client request (any channel of the pool) */
	LINE_PENDING_LSS,     /* LSS master request */
} line_pending_kind;

/* A mailbox request waiting for an asynchronous core completion. */
typedef struct line_pending {
	uint64_t tag;  /* core tag: (generation << 16) | slot */
	uint16_t code; /* mailbox command */
	uint8_t kind;  /* line_pending_kind */
	bool used;
	uint8_t route_ext; /* SDO with a node of a network: the extension that
	                    * routes it (line_ext.h sdo_route); LINE_NO_ROUTE */
	mbx_reply_to reply;
	uint8_t *buf; /* big slots: max_transfer bytes of address space
		       * (mailbox/budget.h); small: inline_data */
	uint32_t cap;
	/* Big slots: an upload is paid from the transfer memory budget as its
	 * data arrives (line_pending_grow); released with the slot, pages
	 * beyond MBX_BUFFER_KEEP included. */
	mbx_budget *budget;
	uint32_t keep_free; /* read-only requester: leave cap to writers */
	uint32_t reserved;
	uint32_t touched;
	bool over_budget; /* the budget refused this upload more room */
	/* An extension's transfer (line_ext.h line_sdo_submit): shapes the
	 * answer; NULL = the plain SDO answer. */
	line_sdo_answer_fn answer;
	void *answer_ctx;
	uint8_t inline_data[LINE_INLINE_MAX]; /* small uploads/downloads */
} line_pending;

typedef struct line_pending_table {
	line_pending slot[LINE_PENDING_MAX];
	uint16_t free_big[LINE_BIG_SLOTS];
	uint16_t free_small[LINE_PENDING_MAX - LINE_BIG_SLOTS];
	uint16_t n_free_big, n_free_small;
	uint16_t used;
} line_pending_table;

/* big_cap: buffer of each big slot (max_transfer); budget: the daemon's
 * transfer memory (NULL = unlimited). 0 or -ENOMEM. */
int line_pending_init(line_pending_table *t, uint32_t big_cap, mbx_budget *budget);
void line_pending_fini(line_pending_table *t);

/* A free slot for this request: big (with a max_transfer buffer) or small
 * (inline buffer); NULL when none of that kind is free. The last free slot
 * of each kind is kept for clients with write access. */
line_pending *line_pending_take(line_pending_table *t, const mbx_request *req,
				line_pending_kind kind, bool big);
/* The slot waiting for this core tag, or NULL (released meanwhile). */
line_pending *line_pending_find(line_pending_table *t, uint64_t tag);
void line_pending_release(line_pending_table *t, line_pending *p);
/* Room for bytes [0, end) of a big slot's buffer, `total` the size the
 * server announced (UINT32_MAX: none): paid from the budget in one go for
 * an announced size, else in MBX_BUFFER_KEEP steps. 0, or -ENOMEM (beyond
 * cap, or the budget is spent: over_budget set). */
int line_pending_grow(line_pending *p, uint32_t end, uint32_t total);
/* Give the slot's budget back now (before its data is copied into the
 * answer, which pays its own); the pages go with line_pending_release. */
void line_pending_pay_back(line_pending *p);

/* Slots in use (for the iteration in line_dispatch.c's client_gone):
 * the i-th slot, used or not, i < LINE_PENDING_MAX. */
static inline line_pending *line_pending_at(line_pending_table *t, unsigned i)
{
	return &t->slot[i];
}

#endif /* COGW_LINES_LINE_PENDING_H */
