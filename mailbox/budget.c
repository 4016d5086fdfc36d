/* SPDX-License-Identifier: MIT */
/*
 * mailbox/budget.c - transfer memory budget and releasable buffers (see
 * budget.h).
 */
#include "mailbox/budget.h"

#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

void mbx_budget_init(mbx_budget *b, uint64_t limit)
{
	b->limit = limit;
	atomic_store(&b->used, 0);
	atomic_store(&b->peak, 0);
	atomic_store(&b->refused, 0);
}

bool mbx_budget_take(mbx_budget *b, uint64_t n, uint64_t keep_free)
{
	uint64_t used, peak;

	if (!b)
		return true;
	used = atomic_load(&b->used);
	do {
		if (b->limit && (n + keep_free > b->limit || used > b->limit - n - keep_free)) {
			atomic_fetch_add(&b->refused, 1);
			return false;
		}
	} while (!atomic_compare_exchange_weak(&b->used, &used, used + n));
	peak = atomic_load(&b->peak);
	while (used + n > peak && !atomic_compare_exchange_weak(&b->peak, &peak, used + n))
		;
	return true;
}

void mbx_budget_give(mbx_budget *b, uint64_t n)
{
	if (b && n)
		atomic_fetch_sub(&b->used, n);
}

uint64_t mbx_budget_used(const mbx_budget *b)
{
	return b ? atomic_load(&((mbx_budget *)b)->used) : 0;
}

static size_t page_size(void)
{
	long p = sysconf(_SC_PAGESIZE);

	return p > 0 ? (size_t)p : 4096u;
}

static size_t round_up(size_t n, size_t page)
{
	return (n + page - 1) / page * page;
}

void *mbx_buffer_reserve(size_t size)
{
	size_t len = round_up(size ? size : 1, page_size());
	void *p = mmap(NULL, len, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);

	if (p == MAP_FAILED)
		return NULL;
	memset(p, 0, size < MBX_BUFFER_KEEP ? size : MBX_BUFFER_KEEP);
	return p;
}

void mbx_buffer_release(void *buf, size_t used)
{
	size_t page = page_size();
	size_t from = round_up(MBX_BUFFER_KEEP, page);
	size_t to = round_up(used, page);

	if (!buf || to <= from)
		return;
	/* A fresh mapping over the range: its pages go back to the kernel in
	 * one call. MADV_DONTNEED would be refused for pages mlockall
	 * locked; the new mapping inherits MCL_FUTURE's lock-on-fault. */
	mmap((uint8_t *)buf + from, to - from, PROT_READ | PROT_WRITE,
	     MAP_PRIVATE | MAP_ANONYMOUS | MAP_FIXED, -1, 0);
}

void mbx_buffer_free(void *buf, size_t size)
{
	if (buf)
		munmap(buf, round_up(size ? size : 1, page_size()));
}
