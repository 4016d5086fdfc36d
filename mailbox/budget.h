/* SPDX-License-Identifier: MIT */
/*
 * mailbox/budget.h - the daemon's transfer memory: one budget shared by
 * every line, and transfer buffers whose pages go back to the kernel after
 * a big transfer (docs/config.md).
 *
 * Why: each line keeps several buffers of max_transfer bytes (mailbox
 * transfer slots, SDO upload slots). Allocated in full and locked by
 * mlockall they pinned 1.2 GB for max_transfer 64 MiB on 3 lines; locked
 * as they are touched (MCL_ONFAULT) they still ended up pinned for good
 * once big transfers had run through them. Now a buffer is only address
 * space: a transfer takes its size from the budget before it touches the
 * buffer (refused when the budget is spent) and, once it is over, gives
 * the size back and returns the pages beyond the first
 * MBX_BUFFER_KEEP bytes to the kernel. So the memory transfers can pin is
 * bounded by the budget, whatever max_transfer and the slot counts are.
 *
 * Threads: the budget is one atomic counter (no lock), taken and given by
 * every line thread; the buffers belong to the line that reserved them.
 */
#ifndef COGW_MAILBOX_BUDGET_H
#define COGW_MAILBOX_BUDGET_H

#include <stdatomic.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* The first bytes of every buffer stay mapped (and are touched at
 * reservation, so small transfers never fault on the line thread). */
#define MBX_BUFFER_KEEP (64u * 1024u)

typedef struct mbx_budget {
	uint64_t limit;           /* bytes; 0 = no limit */
	_Atomic uint64_t used;    /* taken now, all lines */
	_Atomic uint64_t peak;    /* highest used so far */
	_Atomic uint64_t refused; /* takes that did not fit */
} mbx_budget;

void mbx_budget_init(mbx_budget *b, uint64_t limit);
/* Take n bytes, leaving at least keep_free bytes untaken (a read-only
 * client's transfer leaves one max_transfer to writers); false (and
 * counted in refused) if they do not fit. A NULL budget has room for
 * anything. */
bool mbx_budget_take(mbx_budget *b, uint64_t n, uint64_t keep_free);
void mbx_budget_give(mbx_budget *b, uint64_t n);
uint64_t mbx_budget_used(const mbx_budget *b);

/* Reserve a buffer of size bytes (anonymous mapping; the first
 * MBX_BUFFER_KEEP bytes are touched now). NULL on failure. */
void *mbx_buffer_reserve(size_t size);
/* Give back to the kernel the pages of buf beyond MBX_BUFFER_KEEP that a
 * transfer of `used` bytes may have touched (the range becomes fresh
 * zero pages, locked again only when touched under mlockall(MCL_ONFAULT)).
 * Nothing to do for used <= MBX_BUFFER_KEEP. */
void mbx_buffer_release(void *buf, size_t used);
void mbx_buffer_free(void *buf, size_t size);

#endif /* COGW_MAILBOX_BUDGET_H */
