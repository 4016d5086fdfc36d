/* SPDX-License-Identifier: MIT */
/*
 * lines/xring.c - the single-producer single-consumer ring of xring.h.
 *
 * head and tail are free-running 32-bit counters (count = tail - head,
 * wrap-around is harmless with a power-of-two size), each written by one
 * side only and kept on its own cache line. A slot is a 4-byte length
 * followed by msg_max bytes. The producer fills the slot, then publishes
 * it with a release store of tail; the consumer reads it after an acquire
 * load of tail and hands it back with a release store of head.
 */
#include "lines/xring.h"

#include <errno.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <sys/eventfd.h>
#include <unistd.h>

#define CACHE_LINE 64

struct xring {
	/* producer side */
	_Alignas(CACHE_LINE) _Atomic uint32_t tail;
	atomic_uint_fast64_t pushed, dropped, wakes;
	_Atomic uint32_t high_water;
	/* a quiet push left messages the consumer was not woken for: the
	 * next push wakes it whatever it finds (producer only) */
	bool wake_owed;
	/* consumer side */
	_Alignas(CACHE_LINE) _Atomic uint32_t head;
	atomic_uint_fast64_t popped;
	atomic_bool closed;
	/* read-only after creation */
	_Alignas(CACHE_LINE) uint32_t mask;
	uint32_t msg_max;
	size_t stride;
	int wakefd;
	uint8_t *slots;
};

static void add_relaxed(atomic_uint_fast64_t *c)
{
	/* single writer: a plain load + store, no locked instruction */
	atomic_store_explicit(c, atomic_load_explicit(c, memory_order_relaxed) + 1,
			      memory_order_relaxed);
}

int xring_create(xring **out, uint32_t slots, uint32_t msg_max, int wakefd)
{
	*out = NULL;
	if (slots < 2 || slots > 65536 || (slots & (slots - 1)) || msg_max < 1 || msg_max > 65536)
		return -EINVAL;
	xring *r = aligned_alloc(CACHE_LINE,
				 (sizeof *r + CACHE_LINE - 1) / CACHE_LINE * CACHE_LINE);
	if (!r)
		return -ENOMEM;
	memset(r, 0, sizeof *r);
	r->mask = slots - 1;
	r->msg_max = msg_max;
	r->stride = sizeof(uint32_t) + msg_max;
	r->wakefd = wakefd;
	r->slots = calloc(slots, r->stride);
	if (!r->slots) {
		free(r);
		return -ENOMEM;
	}
	atomic_init(&r->tail, 0);
	atomic_init(&r->head, 0);
	atomic_init(&r->closed, false);
	*out = r;
	return 0;
}

void xring_destroy(xring *r)
{
	if (!r)
		return;
	free(r->slots);
	free(r);
}

static uint8_t *slot_at(const xring *r, uint32_t pos)
{
	return r->slots + (size_t)(pos & r->mask) * r->stride;
}

/* wake_below: a push that leaves fewer messages queued does not wake the
 * consumer (xring_push_quiet); 0 = always as the Dekker rule says. */
static int push(xring *r, const void *msg, uint32_t len, uint32_t wake_below)
{
	if (len == 0 || len > r->msg_max)
		return -EMSGSIZE;
	if (atomic_load_explicit(&r->closed, memory_order_acquire)) {
		add_relaxed(&r->dropped);
		return -EPIPE;
	}
	uint32_t t = atomic_load_explicit(&r->tail, memory_order_relaxed);
	uint32_t h = atomic_load_explicit(&r->head, memory_order_acquire);
	uint32_t queued = t - h;
	if (queued > r->mask) {
		add_relaxed(&r->dropped);
		return -ENOBUFS;
	}
	uint8_t *s = slot_at(r, t);
	memcpy(s, &len, sizeof len);
	memcpy(s + sizeof len, msg, len);
	atomic_store_explicit(&r->tail, t + 1, memory_order_release);
	add_relaxed(&r->pushed);
	if (queued + 1 > atomic_load_explicit(&r->high_water, memory_order_relaxed))
		atomic_store_explicit(&r->high_water, queued + 1, memory_order_relaxed);
	if (queued + 1 < wake_below) {
		r->wake_owed = true;
		return 0;
	}
	/* Dekker with xring_pop(): our tail store before our head load. */
	atomic_thread_fence(memory_order_seq_cst);
	if ((atomic_load_explicit(&r->head, memory_order_relaxed) == t || r->wake_owed) &&
	    r->wakefd >= 0) {
		/* the consumer had taken everything before ours (it may
		 * sleep), or was not woken for the quiet ones before it */
		r->wake_owed = false;
		add_relaxed(&r->wakes);
		eventfd_write(r->wakefd, 1);
	}
	return 0;
}

int xring_push(xring *r, const void *msg, uint32_t len)
{
	return push(r, msg, len, 0);
}

int xring_push_quiet(xring *r, const void *msg, uint32_t len, uint32_t wake_at)
{
	return push(r, msg, len, wake_at ? wake_at : 1);
}

int xring_push_wake_later(xring *r, const void *msg, uint32_t len)
{
	return push(r, msg, len, UINT32_MAX);
}

void xring_wake(xring *r)
{
	if (!r->wake_owed || r->wakefd < 0)
		return;
	r->wake_owed = false;
	/* Dekker with xring_pop(), as in push(): a consumer that took every
	 * message (it was awake) has nothing to wake for */
	atomic_thread_fence(memory_order_seq_cst);
	if (atomic_load_explicit(&r->head, memory_order_relaxed) ==
	    atomic_load_explicit(&r->tail, memory_order_relaxed))
		return;
	add_relaxed(&r->wakes);
	eventfd_write(r->wakefd, 1);
}

int xring_pop(xring *r, void *buf, uint32_t cap)
{
	/* Dekker with xring_push(): our previous head store before this tail
	 * load. */
	atomic_thread_fence(memory_order_seq_cst);
	uint32_t h = atomic_load_explicit(&r->head, memory_order_relaxed);
	uint32_t t = atomic_load_explicit(&r->tail, memory_order_acquire);
	if (h == t)
		return 0;
	const uint8_t *s = slot_at(r, h);
	uint32_t len;
	memcpy(&len, s, sizeof len);
	if (len > cap)
		return -EMSGSIZE;
	memcpy(buf, s + sizeof len, len);
	atomic_store_explicit(&r->head, h + 1, memory_order_release);
	add_relaxed(&r->popped);
	return (int)len;
}

void xring_close(xring *r)
{
	atomic_store_explicit(&r->closed, true, memory_order_release);
}

bool xring_is_closed(const xring *r)
{
	return atomic_load_explicit(&((xring *)r)->closed, memory_order_acquire);
}

uint32_t xring_count(const xring *r)
{
	xring *m = (xring *)r;
	uint32_t h = atomic_load_explicit(&m->head, memory_order_acquire);
	uint32_t t = atomic_load_explicit(&m->tail, memory_order_acquire);
	return t - h;
}

void xring_stats_get(const xring *r, xring_stats *out)
{
	xring *m = (xring *)r;
	out->pushed = atomic_load_explicit(&m->pushed, memory_order_relaxed);
	out->popped = atomic_load_explicit(&m->popped, memory_order_relaxed);
	out->dropped = atomic_load_explicit(&m->dropped, memory_order_relaxed);
	out->wakes = atomic_load_explicit(&m->wakes, memory_order_relaxed);
	out->high_water = atomic_load_explicit(&m->high_water, memory_order_relaxed);
}

/* ---- mesh ------------------------------------------------------------------ */

#define MESH_MAX 64u

struct xring_mesh {
	unsigned n;
	bool own_fds;
	int wakefd[MESH_MAX];
	xring *ring[]; /* n x n, [from * n + to], NULL on the diagonal */
};

int xring_mesh_create(xring_mesh **out, unsigned n, const int *wakefds, uint32_t slots,
		      uint32_t msg_max)
{
	*out = NULL;
	if (n < 2 || n > MESH_MAX)
		return -EINVAL;
	xring_mesh *m = calloc(1, sizeof *m + (size_t)n * n * sizeof m->ring[0]);
	if (!m)
		return -ENOMEM;
	m->n = n;
	m->own_fds = !wakefds;
	for (unsigned i = 0; i < n; i++)
		m->wakefd[i] = -1;
	for (unsigned i = 0; i < n; i++) {
		m->wakefd[i] = wakefds ? wakefds[i] : eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
		if (m->wakefd[i] < 0) {
			int rc = wakefds ? -EINVAL : -errno;
			xring_mesh_destroy(m);
			return rc;
		}
	}
	for (unsigned from = 0; from < n; from++) {
		for (unsigned to = 0; to < n; to++) {
			if (from == to)
				continue;
			int rc = xring_create(&m->ring[from * n + to], slots, msg_max,
					      m->wakefd[to]);
			if (rc < 0) {
				xring_mesh_destroy(m);
				return rc;
			}
		}
	}
	*out = m;
	return 0;
}

void xring_mesh_destroy(xring_mesh *m)
{
	if (!m)
		return;
	for (unsigned i = 0; i < m->n * m->n; i++)
		xring_destroy(m->ring[i]);
	for (unsigned i = 0; m->own_fds && i < m->n; i++)
		if (m->wakefd[i] >= 0)
			close(m->wakefd[i]);
	free(m);
}

unsigned xring_mesh_lines(const xring_mesh *m)
{
	return m->n;
}

int xring_mesh_wake_fd(const xring_mesh *m, unsigned to)
{
	return m && to < m->n ? m->wakefd[to] : -1;
}

xring *xring_mesh_get(xring_mesh *m, unsigned from, unsigned to)
{
	if (!m || from >= m->n || to >= m->n || from == to)
		return NULL;
	return m->ring[from * m->n + to];
}
