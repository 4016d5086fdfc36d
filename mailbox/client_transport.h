/* SPDX-License-Identifier: MIT */
/*
 * mailbox/client_transport.h - what the files of libcogw's transport
 * share: the handle, the lines' registrations, the waiting calls and
 * asynchronous requests, and the functions each file offers the files
 * above it. Not installed; hidden from libcogw.so's exported symbols.
 *
 * The files, top to bottom (a file calls only files below it; the
 * services, client_api_*.c, call client_call.c through client_internal.h):
 *   client.c         the handle's life: cogw_open, cogw_close
 *   client_async.c   cogw_send_async, cogw_recv, cogw_event_fd
 *   client_loop.c    the handle for event loops (cogw_loop_*): one
 *                    descriptor, sends that never wait, the upkeep the
 *                    loop runs when cogw_loop_timeout_ms() says
 *   client_call.c    the blocking call: registration on first use, send,
 *                    wait as leader or follower, restarts
 *   client_helper.c  the helper thread: leads for asynchronous answers,
 *                    leases (PING), restarts (re-registration)
 *   client_recv.c    reading the response queue: one message, and what
 *                    it completes (a call, an asynchronous request, a
 *                    re-registration); the XFER_ACKs
 *   client_send.c    a line's command queue and registration; sending a
 *                    command, chunked when it does not fit one message
 * client_recv.c and client_send.c need no thread of their own: the loop
 * handle (client_loop.c) calls them from the application's loop.
 */
#ifndef COGW_MAILBOX_CLIENT_TRANSPORT_H
#define COGW_MAILBOX_CLIENT_TRANSPORT_H

#include <mqueue.h>
#include <pthread.h>
#include <stdbool.h>
#include <stdint.h>
#include <sys/types.h>
#include <time.h>

#include "mailbox/client_internal.h"

#pragma GCC visibility push(hidden)

#define ASYNC_RING 64u
#define DEFAULT_TIMEOUT_MS 5000u

#define RESTART_CHECK_MS 200u

typedef struct waiter {
	struct waiter *next;
	uint64_t corr;
	uint16_t code;
	uint8_t line;
	bool done;
	int status;
	uint32_t abort;
	uint8_t *buf;
	size_t cap;
	size_t len; /* bytes received (may exceed cap: truncated) */
	uint16_t next_chunk;
} waiter;

typedef struct async_op {
	struct async_op *next;
	uint64_t corr;
	uint8_t line;
	uint16_t code;
	int status;
	uint32_t abort;
	uint32_t dropped;
	uint8_t *data;
	size_t len, total;
	uint16_t next_chunk;
	/* monotonic; 0 = none (cogw_send_async: the helper thread's handle).
	 * A loop handle fails a request still unanswered then with
	 * COGW_E_TIMEOUT (client_loop.c): a daemon killed without a
	 * successor leaves no other trace. */
	uint64_t deadline_us;
} async_op;

typedef struct line_state {
	bool registered;
	bool registering; /* a thread is registering: others wait */
	/* The daemon restarted (the command queue behind the name is another
	 * one, or gone): cmd must be re-opened by name and the line
	 * registered again (client_line_ready). */
	bool stale;
	mqd_t cmd;
	ino_t cmd_ino;            /* the queue cmd refers to */
	unsigned restarts;        /* counts restarts seen: a wait that began
	                    * before one fails with COGW_E_RESTARTED */
	unsigned restarts_failed; /* asyncs failed up to this count */
	uint64_t checked_us;      /* last client_cmd_queue_check */
	/* what to subscribe again after a restart */
	uint32_t sub_classes;
	uint8_t n_filters;
	mbx_raw_filter filters[MBX_RAW_FILTERS_MAX];
	/* reader thread: a re-registration sent by itself (event-only
	 * clients make no calls that would re-register) */
	uint64_t rereg_corr;
	uint64_t rereg_sent_us;
	uint32_t client;
	uint64_t token;
	uint32_t lease_ms;
	uint32_t max_msg;
	uint32_t max_transfer;
	/* lease renewal: something was sent since the helper last looked
	 * (at ping_checked_us); if not, it sends a PING. No clock read per send. */
	bool sent_since_ping;
	uint64_t ping_checked_us;
	/* registered once: a loop handle registers it again by itself after
	 * a daemon restart (a helper-thread handle only with subscriptions) */
	bool attached;
} line_state;

struct cogw {
	char instance[MBX_INSTANCE_MAX + 1];
	char resp_name[MBX_QNAME_MAX], evt_name[MBX_QNAME_MAX];
	pid_t pid;
	mqd_t resp, evt;
	size_t resp_msg, evt_msg;
	unsigned resp_depth;
	unsigned timeout_ms;
	pthread_t reader;

	/* Opened with the helper thread (client_helper_start), which is started only
	 * when something needs it: a one-shot handle (open, one call, close)
	 * runs without it (docs/fastpath.md "One-shot cogwctl"). Set under
	 * mu; -1 / false until then. self: O_WRONLY on resp, to wake the
	 * leader; evt_self: O_WRONLY on evt, to wake a cogw_recv() waiting on
	 * it. efd/epfd (cogw_event_fd) may be opened without the helper. */
	bool reader_started;
	mqd_t self, evt_self;
	int efd, epfd;

	/* A loop handle (cogw_loop_open): never a helper thread; epfd also
	 * watches the response queue, the application's loop reads it
	 * (client_loop.c) and calls client_upkeep() a period after
	 * upkeep_last_us;
	 * loop_buf: its receive buffer for the event queue. */
	bool loop;
	/* cogw_loop_recv() is taking in the response queue (h->mu): an answer
	 * it finishes is popped by it at once, so it sets no eventfd */
	bool loop_taking;
	/* the latest clock reading of cogw_loop_tick or cogw_loop_send:
	 * cogw_loop_timeout_ms counts from it (one clock read less a turn) */
	uint64_t loop_now_us;
	uint64_t upkeep_last_us;
	uint8_t *loop_buf;

	pthread_mutex_t mu;         /* everything below */
	pthread_cond_t cond;        /* waiters: an answer came, or the lead is free */
	pthread_cond_t reader_cond; /* the helper thread: an async is due, closing */
	bool closing;
	/* A thread is reading the response queue, until lead_until_us
	 * (monotonic) at the latest; lead_buf is its receive buffer. */
	bool leader;
	uint64_t lead_until_us;
	uint8_t *lead_buf;
	/* cogw_recv() callers waiting in mq_timedreceive on the event queue
	 * (no asynchronous answer can come meanwhile), the latest one's slice
	 * end; efd_set: the eventfd was written and not read since. */
	unsigned evt_waiters;
	uint64_t evt_wait_until_us;
	bool efd_set;
	uint64_t next_corr;
	waiter *waiters;
	async_op *asyncs;
	cogw_msg ring[ASYNC_RING];
	unsigned ring_head, ring_count;
	cogw_stats stats;

	/* The line table. Held only briefly (never across a wait), so the
	 * reader thread can always take it to send an XFER_ACK or a PING. */
	pthread_mutex_t setup_mu;
	pthread_cond_t setup_cond; /* registration finished */
	line_state lines[MBX_LINES_MAX];
};

/* Correlation ids of the reader thread's own re-registrations: never
 * one of client_corr_new()'s. */
#define REREG_CORR_BIT (1ull << 63)

static inline uint64_t mono_us(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static inline struct timespec mono_deadline(uint64_t at_us)
{
	return (struct timespec){ .tv_sec = (time_t)(at_us / 1000000u),
				  .tv_nsec = (long)(at_us % 1000000u) * 1000L };
}

/* CLOCK_REALTIME deadline for mq_timed*: until_us (monotonic) as seen at
 * now (monotonic, read by the caller: in a VM every clock read can be a
 * system call); {0, 0} = already passed (do not wait). */
static inline struct timespec realtime_deadline(uint64_t now, uint64_t until_us)
{
	struct timespec at = { 0, 0 };
	uint64_t left;

	if (until_us <= now)
		return at;
	left = until_us - now;
	clock_gettime(CLOCK_REALTIME, &at);
	at.tv_sec += (time_t)(left / 1000000u);
	at.tv_nsec += (long)(left % 1000000u) * 1000L;
	if (at.tv_nsec >= 1000000000L) {
		at.tv_sec++;
		at.tv_nsec -= 1000000000L;
	}
	return at;
}

static inline unsigned ms_left(uint64_t deadline_us)
{
	uint64_t now = mono_us();

	return now >= deadline_us ? 0 : (unsigned)((deadline_us - now + 999) / 1000);
}

/* ---- client_loop.c ------------------------------------------------------------ */

/* Make a fresh handle a loop handle: its receive buffer, the loop
 * descriptor watching the response queue too. 0 or a cogw_err. */
int client_loop_setup(cogw *h);
/* cogw_recv() on a loop handle: cogw_loop_recv(), and between tries a
 * poll() of the loop descriptor and the upkeep, up to timeout_ms. */
int client_loop_wait(cogw *h, cogw_msg *m, int timeout_ms);

/* ---- client_call.c ------------------------------------------------------------ */

/* Register with a line on first use. One thread registers, others that
 * need the same line meanwhile wait for it. now: the caller's clock
 * reading (the registration's wait and lease bookkeeping start there). */
int client_line_ready(cogw *h, unsigned line, uint64_t now, uint64_t deadline_us);

/* ---- client_helper.c ---------------------------------------------------------- */

/* Start the helper thread (h->mu held) when the first thing that needs it
 * comes; client_helper_ensure() takes h->mu itself. 0 or a cogw_err. */
int client_helper_start(cogw *h);
int client_helper_ensure(cogw *h);
/* The eventfd and epoll descriptor of cogw_event_fd(), opened on first
 * need (h->mu held). */
int client_event_fds_open(cogw *h);
/* What the helper thread does on each wake-up, for a handle without one:
 * PINGs the lines whose lease needs it, looks for daemon restarts (fails
 * the asynchronous requests of a restarted line, registers it again).
 * Call without h->mu. */
void client_upkeep(cogw *h);
/* How long (ms) until the upkeep is due again: a sixth of the shortest
 * lease, at most a second. */
unsigned client_upkeep_period_ms(cogw *h);

/* ---- client_recv.c ------------------------------------------------------------ */

/* As the leader (h->leader set, h->mu not held): receive and handle one
 * message, waiting until until_us (monotonic) at most. 1 a message, 0
 * none (timeout, signal, a wake-up), -1 the queue is unusable. */
int client_lead_read(cogw *h, uint64_t now, uint64_t until_us);
/* Step down as leader (h->mu held): a waiting caller, else the helper
 * thread when an asynchronous answer is due, takes the lead. */
void client_lead_release(cogw *h);
/* An asynchronous answer for cogw_recv() (h->mu held): dropped and
 * counted when the ring is full. */
void client_ring_push(cogw *h, cogw_msg *m);
/* A request whose answer whoever reads the response queue will queue in
 * the ring, announced before it is sent (the answer may come at once);
 * deadline_us: see async_op. NULL when out of memory. */
async_op *client_async_add(cogw *h, unsigned line, uint16_t cmd, uint64_t id, uint64_t deadline_us);
/* A request that could not be sent: no answer will come. */
void client_async_drop(cogw *h, async_op *a);
/* The oldest asynchronous answer of the ring into *m (h->mu not held):
 * true when there was one; the eventfd is read when the ring empties. */
bool client_ring_pop(cogw *h, cogw_msg *m);
/* One event from the event queue into *m, buf its receive buffer
 * (h->evt_msg bytes), waiting until until_us (monotonic; 0: not at all):
 * 1 got one, 0 none, < 0 a cogw_err. */
int client_event_pop(cogw *h, cogw_msg *m, uint8_t *buf, uint64_t now, uint64_t until_us);

/* ---- client_send.c ------------------------------------------------------------ */

/* Send a command (corr, flags) to the line, chunked when fixed + data do
 * not fit one message; waits for room up to deadline_us. 0 or a
 * cogw_err. */
int client_send_cmd(cogw *h, unsigned line, uint16_t code, uint8_t flags, uint64_t corr,
		    const void *fixed, size_t flen, const void *data, size_t dlen,
		    uint64_t deadline_us);
/* Is the line's command queue still the daemon's? 0, or COGW_E_RESTARTED
 * (the line is then stale and unregistered, its restart count up). */
int client_cmd_queue_check(cogw *h, unsigned line);
unsigned client_restarts_of(cogw *h, unsigned line);
/* (Re-)open the line's command queue by name (setup_mu held). */
int client_line_open_cmd(cogw *h, unsigned line);
/* The REGISTER request naming the handle's queues. */
void client_register_req(const cogw *h, mbx_register_req *rq);
/* The line's registration as the daemon answered it (setup_mu held). */
void client_line_registered(line_state *ls, const mbx_register_resp *rs, uint64_t now);
/* A correlation id unique in the handle. */
uint64_t client_corr_new(cogw *h);

#pragma GCC visibility pop

#endif
