/* SPDX-License-Identifier: MIT */
/*
 * mailbox/server.c - the daemon side of one line's mailbox.
 *
 * Design notes (why it looks like this):
 * - One server per line, driven by that line's thread only: the client
 *   table is per line, so a line never waits for a lock another line holds
 *   (docs/architecture.md "Threads and data flow").
 * - Every send to a client is mq_send on an O_NONBLOCK descriptor. A full
 *   client queue means the message is dropped and counted, and the next
 *   message that reaches that queue carries MBX_F_OVERFLOW + the count; an
 *   MBX_EV_OVERFLOW notice follows on the event queue as soon as it has
 *   room. A slow client therefore costs the line one failed syscall per
 *   message, never a stall.
 * - Access control rests on two kernel facts: the owner of a message queue
 *   is the user that created it (fstat on the mqd gives st_uid on Linux),
 *   and a queue with mode 0600 can be read only by that user. The server
 *   sends a random 64-bit token in the REGISTER answer to the response
 *   queue; every later command must carry it. So a process can only act as
 *   a client whose response queue it can read, and it is granted the rights
 *   of that queue's owner. Naming somebody else's queue in REGISTER gains
 *   nothing (the token goes to that queue).
 * - No allocation after create: the client table, the transfer slots and
 *   both message buffers are sized from the config. A transfer slot's
 *   buffer is address space: a transfer pays its size from the budget
 *   shared by all lines before it touches the buffer, and gives the pages
 *   beyond MBX_BUFFER_KEEP back when it ends (mailbox/budget.h), so what
 *   transfers pin is bounded by the budget, not by max_transfer x slots.
 */
#include "mailbox/server.h"

#include <errno.h>
#include <fcntl.h>
#include <mqueue.h>
#include <signal.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#define RETRY_US 20000u /* resume a chunk stream / overflow notice */
/* A tick later than this past the time it asked for means this thread (or
 * the whole machine) stood still: see forgive_late_wake. */
#define LATE_WAKE_US 100000u
/* At most one unsolicited REGISTER answer (a refusal, or the answer of a
 * registration not confirmed yet, again) per this interval to the queues
 * of one user, resp. of one registration: whoever sends REGISTER may not
 * be that user (docs/mailbox.md "Security model"). */
#define REG_ANSWER_INTERVAL_US 100000u
/* Users whose REGISTER refusals are tracked at once (least recent out). */
#define REFUSAL_SENDERS 8u

typedef struct mbx_client {
	uint32_t id; /* 0 = free slot */
	uint64_t token;
	mqd_t resp, evt;
	size_t resp_msg, evt_msg; /* mq_msgsize of each */
	unsigned resp_depth;      /* mq_maxmsg of the response queue */
	ino_t resp_ino, evt_ino;  /* to notice a queue that was replaced */
	uint32_t uid, pid;
	uint8_t access;
	bool confirmed;
	bool pid_proven;      /* at REGISTER, pid was a live process of uid */
	bool pid_disputed;    /* REGISTERs named other pids: pid tells nothing */
	uint64_t answered_us; /* last REGISTER answer sent */
	bool dead;            /* a send failed hard: reap at the next tick */
	uint32_t classes;
	uint8_t n_filters;
	mbx_raw_filter filters[MBX_RAW_FILTERS_MAX];
	uint64_t registered_us;
	uint64_t lease_until;
	uint32_t drop_resp, drop_evt; /* not yet reported to the client */
	uint16_t outstanding;         /* dispatched, not answered yet */
	uint64_t dropped;
	bool discarding; /* chunks of a refused transfer are ignored */
	uint64_t discard_corr;
	char resp_name[MBX_QNAME_MAX];
	char evt_name[MBX_QNAME_MAX];
} mbx_client;

typedef enum xfer_state {
	XS_FREE = 0,
	XS_IN,   /* receiving a chunked command */
	XS_HELD, /* complete, dispatched, data referenced until answered */
	XS_OUT,  /* streaming a chunked response */
} xfer_state;

typedef struct mbx_xfer {
	xfer_state st;
	uint32_t client;
	uint64_t corr;
	uint16_t code;
	uint8_t hflags; /* command header flags (NO_REPLY) */
	uint8_t fixed[64];
	size_t fixed_len;
	uint8_t *buf;    /* cfg.max_transfer bytes of address space */
	size_t touched;  /* bytes of buf written since its pages were given back */
	size_t reserved; /* taken from cfg.budget for this transfer */
	size_t total, done;
	uint16_t next_chunk; /* in: expected; out: next to send */
	uint16_t acked;      /* out: client consumed chunks below this */
	int status;
	uint32_t abort;
	uint64_t deadline_us; /* progress timeout */
	uint64_t end_us;      /* lifetime (xfer_max_ms), however it goes */
	uint64_t retry_us;    /* out: resume sending at (0 = not waiting) */
} mbx_xfer;

struct mbx_server {
	mbx_server_config cfg; /* with defaults filled in */
	char qname[MBX_QNAME_MAX];
	mqd_t q;
	ino_t q_ino; /* never accepted as a client queue */
	uint8_t *rx;
	size_t rx_size;
	uint8_t *tx;
	mbx_access_rule *rules;
	size_t rules_cap; /* room for MBX_SERVER_RULES_MAX (set_rules) */
	mbx_client *clients;
	/* Subscribers by event class: for class bit b, bit i of the words
	 * sub_bits[b * sub_words ..] says client slot i subscribed to it, so a
	 * publish visits the subscribers of its class only (each line has its
	 * own server: class x line). */
	uint64_t *sub_bits;
	size_t sub_words;
	mbx_xfer *xfers;
	uint16_t gen;
	uint64_t rng; /* fallback token source */
	uint64_t now_us;
	uint64_t next_check_us;
	uint64_t wake_by_us; /* what the last tick asked for */
	/* REGISTER refusals by the owner of the queues they named: the
	 * only sender identity the kernel confirms (docs/mailbox.md). */
	struct refusal_sender {
		uint32_t uid;
		uint64_t refused;
		uint64_t seen_us, answered_us;
	} refusals[REFUSAL_SENDERS];
	mbx_server_stats stats;
};

/* ---- helpers -------------------------------------------------------------- */

static uint64_t splitmix(uint64_t *s)
{
	uint64_t z = (*s += 0x9E3779B97F4A7C15ull);

	z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
	z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
	return z ^ (z >> 31);
}

static uint64_t new_token(mbx_server *srv)
{
	uint64_t t = 0;

	/* getrandom never blocks once the pool is initialised (GRND_NONBLOCK
	 * guards early boot); the fallback is unpredictable enough only
	 * against a casual local user, so it is mixed with the clock. */
	if (getrandom(&t, sizeof t, GRND_NONBLOCK) != (ssize_t)sizeof t) {
		struct timespec ts;

		clock_gettime(CLOCK_MONOTONIC, &ts);
		srv->rng ^= (uint64_t)ts.tv_nsec << 17 ^ (uint64_t)ts.tv_sec;
		t = splitmix(&srv->rng);
	}
	return t ? t : 1;
}

static mbx_client *client_find(const mbx_server *srv, uint32_t id)
{
	uint32_t idx = (id & 0xFFFFu);

	if (id == 0 || idx == 0 || idx > srv->cfg.max_clients)
		return NULL;
	mbx_client *c = &srv->clients[idx - 1];

	return c->id == id ? c : NULL;
}

static uint8_t access_of(const mbx_server *srv, uint32_t uid)
{
	if (uid == 0)
		return MBX_ACCESS_WRITE;
	for (size_t i = 0; i < srv->cfg.n_rules; i++)
		if (srv->rules[i].uid == uid)
			return srv->rules[i].access;
	return srv->cfg.default_access;
}

static void count_bad(mbx_server *srv, mbx_bad b)
{
	if (b >= MBX_BAD_COUNT)
		b = MBX_BAD_NONE;
	srv->stats.malformed[b]++;
	srv->stats.malformed_total++;
}

/* End a transfer: its budget goes back now; its pages too, unless the
 * caller still reads the buffer (mbx_server_respond: an answer may live in
 * the request's data) and gives them back itself once it is copied. */
static void xfer_end(mbx_server *srv, mbx_xfer *x, bool keep_pages)
{
	uint8_t *buf = x->buf;
	size_t touched = x->touched;

	mbx_budget_give(srv->cfg.budget, x->reserved);
	memset(x, 0, sizeof *x);
	x->buf = buf;
	x->touched = touched;
	if (!keep_pages && x->touched > MBX_BUFFER_KEEP) {
		mbx_buffer_release(x->buf, x->touched);
		x->touched = MBX_BUFFER_KEEP;
	}
}

static void xfer_free(mbx_server *srv, mbx_xfer *x)
{
	xfer_end(srv, x, false);
}

/* Mark bytes [0, n) of the slot's buffer as about to be written. */
static void xfer_touch(mbx_xfer *x, size_t n)
{
	if (n > x->touched)
		x->touched = n;
}

/* ---- sending ------------------------------------------------------------------ */

enum send_mode {
	SEND_NORMAL, /* a full queue = a dropped message */
	SEND_STREAM, /* a full queue = wait (flow-controlled chunk stream) */
};

/* Send the message encoded in srv->tx (n bytes) to a client's response
 * or event queue, without blocking, readdressed to it (id, and the count
 * of its messages lost before this one). Returns 0, -EAGAIN (stream: queue
 * full), -ENOBUFS (dropped), -EPIPE (queue unusable: client marked dead). */
static int deliver(mbx_server *srv, mbx_client *c, bool event, size_t n, enum send_mode mode)
{
	uint32_t *pending = event ? &c->drop_evt : &c->drop_resp;

	mbx_hdr_set_recipient(srv->tx, c->id, *pending);
	if (mq_send(event ? c->evt : c->resp, (const char *)srv->tx, n, 0) == 0) {
		*pending = 0;
		if (event)
			srv->stats.events_sent++;
		else
			srv->stats.responses_sent++;
		return 0;
	}
	if (errno == EAGAIN) {
		if (mode == SEND_STREAM)
			return -EAGAIN;
		(*pending)++;
		c->dropped++;
		srv->stats.dropped++;
		return -ENOBUFS;
	}
	/* EBADF & co: the descriptor is unusable; reap at the next tick */
	c->dead = true;
	return -EPIPE;
}

/* Encode one message into srv->tx (addressed to nobody yet). */
static int encode(mbx_server *srv, bool event, mbx_hdr *h, const void *payload, size_t len)
{
	h->magic = MBX_MAGIC;
	h->version = MBX_VERSION;
	h->kind = event ? MBX_KIND_EVENT : MBX_KIND_RESPONSE;
	h->line = srv->cfg.line;
	h->client = 0;
	h->token = 0;
	h->flags &= (uint8_t)~MBX_F_OVERFLOW;
	h->dropped = 0;
	return mbx_msg_build(srv->tx, MBX_MSG_MAX, h, payload, len);
}

/* Send one message to a client's response or event queue, without
 * blocking: encode + deliver. */
static int send_to(mbx_server *srv, mbx_client *c, bool event, mbx_hdr *h, const void *payload,
		   size_t len, enum send_mode mode)
{
	int n = encode(srv, event, h, payload, len);

	if (n < 0 || (size_t)n > (event ? c->evt_msg : c->resp_msg))
		return -EMSGSIZE;
	return deliver(srv, c, event, (size_t)n, mode);
}

/* Keep the class index of client c in step with c->classes (and c->id:
 * a free slot subscribes to nothing). */
static void sub_index_update(mbx_server *srv, const mbx_client *c)
{
	size_t slot = (size_t)(c - srv->clients);
	uint64_t bit = 1ull << (slot % 64);

	for (unsigned b = 0; b < 32; b++) {
		uint64_t *w = &srv->sub_bits[b * srv->sub_words + slot / 64];

		if (c->id && (c->classes & (1u << b)))
			*w |= bit;
		else
			*w &= ~bit;
	}
}

static int send_status(mbx_server *srv, mbx_client *c, uint16_t code, uint64_t corr, int status,
		       uint32_t abort, const void *payload, size_t len)
{
	mbx_hdr h = { .code = code, .corr = corr, .status = status, .abort = abort };

	return send_to(srv, c, false, &h, payload, len, SEND_NORMAL);
}

/* ---- client lifetime ---------------------------------------------------------- */

static void client_remove(mbx_server *srv, mbx_client *c, bool reaped)
{
	uint32_t id = c->id;

	for (unsigned i = 0; i < srv->cfg.xfer_slots; i++) {
		mbx_xfer *x = &srv->xfers[i];

		/* HELD slots stay: the glue may still point an SDO transfer
		 * at their data; answering the request frees them. */
		if (x->client == id && (x->st == XS_IN || x->st == XS_OUT)) {
			srv->stats.xfer_failed++;
			xfer_free(srv, x);
		}
	}
	if (c->resp != (mqd_t)-1)
		mq_close(c->resp);
	if (c->evt != (mqd_t)-1)
		mq_close(c->evt);
	memset(c, 0, sizeof *c);
	c->resp = c->evt = (mqd_t)-1;
	sub_index_update(srv, c);
	srv->stats.clients--;
	if (reaped)
		srv->stats.clients_reaped++;
	else
		srv->stats.clients_unregistered++;
	if (srv->cfg.dispatch.client_gone)
		srv->cfg.dispatch.client_gone(srv->cfg.dispatch_ctx, srv, id);
}

/* Is the queue behind name still the one we hold open? An unlinked (or
 * unlinked and re-created) queue means the client went away. */
static bool queue_still_there(const char *name, ino_t ino)
{
	mqd_t q = mq_open(name, O_WRONLY | O_NONBLOCK | O_CLOEXEC);
	struct stat st;
	bool same;

	if (q == (mqd_t)-1)
		return errno != ENOENT; /* EACCES & co: cannot tell, assume ok */
	same = fstat((int)q, &st) == 0 && st.st_ino == ino;
	mq_close(q);
	return same;
}

/* The process of a reaped client is gone: remove its queues too, so that a
 * crashed client does not leave its names (and kernel memory, counted in
 * its owner's RLIMIT_MSGQUEUE) behind. Only a queue that is still the very
 * one the client registered is removed, never a newcomer's of that name.
 *
 * REGISTER is sent by a process the daemon cannot see, so the queues are
 * removed only when they provably belonged to the dead process: the entry
 * was confirmed (whoever used it read the token, i.e. could read the
 * response queue, i.e. is its owner) and its pid was, at REGISTER, a live
 * process of that owner (pid_check). Anybody else naming those queues, a
 * dead pid or somebody else's pid (in older daemons that unlinked other
 * clients' queues and its own command queues) unlinks nothing. */
static void unlink_orphan_queues(const mbx_client *c)
{
	if (!c->confirmed || !c->pid_proven || c->pid_disputed)
		return;
	if (kill((pid_t)c->pid, 0) == 0 || errno != ESRCH)
		return;
	if (queue_still_there(c->resp_name, c->resp_ino))
		mq_unlink(c->resp_name);
	if (queue_still_there(c->evt_name, c->evt_ino))
		mq_unlink(c->evt_name);
}

/* A full lease from now (any command renews it; 0 = no lease, never read). */
static void lease_renew(const mbx_server *srv, mbx_client *c, uint64_t now_us)
{
	c->lease_until = now_us + (uint64_t)srv->cfg.lease_ms * 1000u;
}

static bool client_is_dead(const mbx_server *srv, const mbx_client *c, uint64_t now_us,
			   bool full_check)
{
	if (c->dead)
		return true;
	if (srv->cfg.lease_ms && now_us > c->lease_until)
		return true;
	if (!c->confirmed &&
	    now_us > c->registered_us + (uint64_t)srv->cfg.register_timeout_ms * 1000u)
		return true;
	if (!full_check)
		return false;
	if (!c->pid_disputed && kill((pid_t)c->pid, 0) < 0 && errno == ESRCH)
		return true;
	return !queue_still_there(c->resp_name, c->resp_ino) ||
	       !queue_still_there(c->evt_name, c->evt_ino);
}

/* ---- transfers ------------------------------------------------------------------ */

static mbx_xfer *xfer_find(mbx_server *srv, uint32_t client, uint64_t corr, xfer_state st)
{
	for (unsigned i = 0; i < srv->cfg.xfer_slots; i++) {
		mbx_xfer *x = &srv->xfers[i];

		if (x->st == st && x->client == client && x->corr == corr)
			return x;
	}
	return NULL;
}

/* A free transfer slot for client c and a transfer of size bytes, or NULL
 * with *status: a client holds at most xfer_per_client slots, and
 * read-only clients together leave one slot to writers (a reader that
 * never acknowledges its big answers must not make a writer's download
 * fail with BUSY) - MBX_E_BUSY; the size must fit the transfer memory
 * budget of all lines - MBX_E_NO_MEMORY. A refusal by a limit or by the
 * budget is counted here, the failed transfer by the caller. */
static mbx_xfer *xfer_alloc(mbx_server *srv, const mbx_client *c, size_t size, int *status)
{
	unsigned mine = 0, readers = 0;
	mbx_xfer *free_slot = NULL;

	for (unsigned i = 0; i < srv->cfg.xfer_slots; i++) {
		mbx_xfer *x = &srv->xfers[i];

		if (x->st == XS_FREE) {
			if (!free_slot)
				free_slot = x;
			continue;
		}
		if (x->client == c->id)
			mine++;
		const mbx_client *o = client_find(srv, x->client);

		if (o && o->access < MBX_ACCESS_WRITE)
			readers++;
	}
	*status = MBX_E_BUSY;
	if (free_slot && (mine >= srv->cfg.xfer_per_client ||
			  (c->access < MBX_ACCESS_WRITE && srv->cfg.xfer_slots > 1 &&
			   readers + 1 >= srv->cfg.xfer_slots))) {
		srv->stats.limited++;
		free_slot = NULL;
	}
	/* read-only clients leave one max_transfer of the budget to writers */
	if (free_slot &&
	    !mbx_budget_take(srv->cfg.budget, size,
			     c->access < MBX_ACCESS_WRITE ? srv->cfg.max_transfer : 0)) {
		*status = MBX_E_NO_MEMORY;
		srv->stats.budget_refused++;
		free_slot = NULL;
	}
	if (!free_slot)
		return NULL; /* the caller counts the failed transfer */
	*status = 0;
	free_slot->reserved = size;
	free_slot->end_us = srv->now_us + (uint64_t)srv->cfg.xfer_max_ms * 1000u;
	return free_slot;
}

static size_t chunk_size(const mbx_client *c)
{
	return c->resp_msg - MBX_HDR_SIZE;
}

/* At most this many chunks unacknowledged in the client's response queue:
 * half of it, so answers to other requests still find room. */
static unsigned stream_window(const mbx_client *c)
{
	unsigned w = c->resp_depth / 2;

	return w ? w : 1;
}

/* Push chunks of an outgoing transfer while the window and the queue
 * allow. */
static void xfer_pump(mbx_server *srv, mbx_xfer *x)
{
	mbx_client *c = client_find(srv, x->client);
	size_t csz;

	if (!c) {
		xfer_free(srv, x);
		return;
	}
	csz = chunk_size(c);
	x->retry_us = 0;
	while (x->done < x->total) {
		size_t n = x->total - x->done;
		int rc;

		if ((unsigned)(x->next_chunk - x->acked) >= stream_window(c))
			return; /* wait for XFER_ACK */
		if (n > csz)
			n = csz;
		mbx_hdr h = {
			.code = x->code,
			.corr = x->corr,
			.status = x->status,
			.abort = x->abort,
			.flags = MBX_F_CHUNKED | (x->done + n < x->total ? MBX_F_MORE : 0),
			.chunk = x->next_chunk,
			.total = (uint32_t)x->total,
		};
		rc = send_to(srv, c, false, &h, x->buf + x->done, n, SEND_STREAM);
		if (rc == -EAGAIN) {
			x->retry_us = srv->now_us + RETRY_US;
			return;
		}
		if (rc < 0) {
			srv->stats.xfer_failed++;
			xfer_free(srv, x);
			return;
		}
		x->done += n;
		x->next_chunk++;
		x->deadline_us = srv->now_us + (uint64_t)srv->cfg.xfer_timeout_ms * 1000u;
	}
	srv->stats.xfer_out++;
	xfer_free(srv, x);
}

/* ---- dispatch --------------------------------------------------------------------- */

static unsigned read_outstanding(const mbx_server *srv)
{
	unsigned n = 0;

	for (unsigned i = 0; i < srv->cfg.max_clients; i++)
		if (srv->clients[i].id && srv->clients[i].access < MBX_ACCESS_WRITE)
			n += srv->clients[i].outstanding;
	return n;
}

/* The request's own timeout (SDO per frame, LSS per answer) within the
 * ceiling: 0xFFFFFFFF would hold an SDO channel for ever. */
static bool timeout_too_long(const mbx_server *srv, const mbx_hdr *h, const uint8_t *p)
{
	uint32_t t;

	switch (h->code) {
	case MBX_CMD_SDO_UPLOAD:
	case MBX_CMD_SDO_DOWNLOAD:
		memcpy(&t, p + offsetof(mbx_sdo_req, timeout_ms), sizeof t);
		break;
	case MBX_CMD_LSS_SWITCH_GLOBAL ... MBX_CMD_LSS_FASTSCAN:
		memcpy(&t, p + offsetof(mbx_lss_req, timeout_ms), sizeof t);
		break;
	default:
		return false;
	}
	return t > srv->cfg.max_request_timeout_ms;
}

static void dispatch(mbx_server *srv, mbx_client *c, const mbx_hdr *h, const uint8_t *fixed,
		     size_t fixed_len, const uint8_t *data, size_t data_len, mbx_xfer *held)
{
	mbx_request req = {
		.reply = { .client = c->id,
			   .code = h->code,
			   .flags = h->flags & MBX_F_NO_REPLY,
			   .corr = h->corr },
		.code = h->code,
		.line = srv->cfg.line,
		.access = c->access,
		.uid = c->uid,
		.pid = c->pid,
		.payload = fixed,
		.fixed_len = fixed_len,
		.data = data,
		.data_len = data_len,
	};

	if (held)
		req.reply.slot = (uint8_t)(held - srv->xfers + 1);
	srv->stats.commands_ok++;
	/* Counted until mbx_server_respond(); over a limit the request is
	 * answered BUSY at once (which uncounts it again). */
	c->outstanding++;
	if (c->outstanding > srv->cfg.max_outstanding ||
	    (c->access < MBX_ACCESS_WRITE && read_outstanding(srv) > srv->cfg.read_outstanding)) {
		srv->stats.limited++;
		mbx_server_respond(srv, &req.reply, MBX_E_BUSY, 0, NULL, 0);
		return;
	}
	if (!srv->cfg.dispatch.dispatch) {
		mbx_server_respond(srv, &req.reply, MBX_E_UNSUPPORTED, 0, NULL, 0);
		return;
	}
	srv->cfg.dispatch.dispatch(srv->cfg.dispatch_ctx, srv, &req);
}

/* ---- protocol commands -------------------------------------------------------- */

/* Open a client queue for sending and check it. Returns the mqd or -1 with
 * *status set. */
static mqd_t open_client_queue(mbx_server *srv, const char *name, struct stat *st,
			       struct mq_attr *attr, int *status)
{
	mqd_t q = mq_open(name, O_WRONLY | O_NONBLOCK | O_CLOEXEC);

	if (q == (mqd_t)-1) {
		*status = MBX_E_QUEUE;
		return q;
	}
	if (fstat((int)q, st) < 0 || mq_getattr(q, attr) < 0) {
		*status = MBX_E_QUEUE;
	} else if (st->st_mode & srv->cfg.forbidden_client_mode) {
		*status = MBX_E_ACCESS; /* others could read the token */
	} else if (attr->mq_msgsize < (long)MBX_MSG_MIN) {
		*status = MBX_E_QUEUE;
	} else {
		*status = 0;
		return q;
	}
	mq_close(q);
	return (mqd_t)-1;
}

/* Is pid a live process running as uid (any of its real, effective, saved
 * or file-system uids)? 1 yes, 0 it runs as somebody else, -ESRCH no such
 * process, -EACCES cannot tell (procfs hidden). The process that created
 * a queue had the owner's fs uid then; a pid of another user, or of
 * nobody, is a REGISTER lying about who sent it. Read into a stack buffer
 * with read(2), not through stdio: fopen would allocate its FILE and
 * buffer on the line thread (no malloc after start-up there) and fstat
 * the file to size that buffer (docs/fastpath.md "One-shot `cogwctl`"). */
static int pid_check(uint32_t pid, uint32_t uid)
{
	char path[32], text[1024];
	unsigned long u[4];
	size_t len = 0;
	ssize_t got;
	int rc = -EACCES;

	snprintf(path, sizeof path, "/proc/%u/status", (unsigned)pid);
	int fd = open(path, O_RDONLY | O_CLOEXEC);

	if (fd < 0) {
		if (kill((pid_t)pid, 0) < 0 && errno == ESRCH)
			return -ESRCH;
		return -EACCES;
	}
	/* The Uid: line is the ninth, a few hundred bytes in; read until it
	 * is complete (procfs hands the file out in one read as a rule). */
	const char *uid_line = NULL;

	while (len < sizeof text - 1 && (got = read(fd, text + len, sizeof text - 1 - len)) > 0) {
		len += (size_t)got;
		text[len] = '\0';
		uid_line = strncmp(text, "Uid:", 4) == 0 ? text : strstr(text, "\nUid:");
		if (uid_line && strchr(uid_line + 1, '\n'))
			break;
		uid_line = NULL;
	}
	close(fd);
	if (!uid_line)
		return rc;
	uid_line += *uid_line == '\n' ? 5 : 4;
	if (sscanf(uid_line, "%lu %lu %lu %lu", &u[0], &u[1], &u[2], &u[3]) != 4)
		return rc;
	rc = 0;
	for (int i = 0; i < 4; i++)
		if (u[i] == uid)
			rc = 1;
	return rc;
}

typedef struct reg_queues {
	mqd_t resp, evt;
	struct stat rst, est;
	struct mq_attr rattr, eattr;
} reg_queues;

/* The refusal record of the user uid (the least recently seen one is
 * reused for a newcomer). */
static struct refusal_sender *refusal_sender_of(mbx_server *srv, uint32_t uid)
{
	struct refusal_sender *lru = &srv->refusals[0];

	for (unsigned i = 0; i < REFUSAL_SENDERS; i++) {
		struct refusal_sender *s = &srv->refusals[i];

		if (s->refused && s->uid == uid)
			return s;
		if (!s->refused || (lru->refused && s->seen_us < lru->seen_us))
			lru = s;
	}
	memset(lru, 0, sizeof *lru);
	lru->uid = uid;
	return lru;
}

/* A REGISTER refused, counted for the owner of the queues it named (the
 * only sender identity the kernel confirms). Whoever sent it may be
 * somebody else, so the refusal is written to the response queue only
 * when it is about that owner (its access, its quota, its event queue) -
 * never when the REGISTER's claims do not match the queues - and then at
 * most once per REG_ANSWER_INTERVAL_US per owner: a flood of REGISTERs
 * naming a victim's queues must not become a flood into them. */
static void register_refuse(mbx_server *srv, const reg_queues *q, const mbx_hdr *h, int status,
			    bool about_owner)
{
	struct refusal_sender *s = refusal_sender_of(srv, (uint32_t)q->rst.st_uid);
	mbx_client tmp = { .resp = q->resp,
			   .evt = (mqd_t)-1,
			   .resp_msg = (size_t)q->rattr.mq_msgsize };

	s->refused++;
	s->seen_us = srv->now_us;
	srv->stats.reg_refused++;
	if (status == MBX_E_ACCESS)
		srv->stats.access_denied++;
	if (h->flags & MBX_F_NO_REPLY)
		return;
	if (!about_owner || srv->now_us < s->answered_us) {
		srv->stats.reg_unanswered++;
		return;
	}
	s->answered_us = srv->now_us + REG_ANSWER_INTERVAL_US;
	/* through a temporary client record: the normal send path (size
	 * checks, non-blocking); no token is given */
	send_status(srv, &tmp, h->code, h->corr, status, 0, NULL, 0);
}

/* Do the REGISTER's claims match the queues? 0 or MBX_E_ACCESS: both
 * queues of one owner, the claimed uid that owner, neither queue this
 * line's command queue, and the claimed pid a live process of the owner.
 * *pid_rc: pid_check's answer (1 = proven). */
static int register_identity(const mbx_server *srv, const mbx_register_req *r,
			     const struct stat *rst, const struct stat *est, int *pid_rc)
{
	*pid_rc = -EACCES;
	if (est->st_uid != rst->st_uid || r->uid != (uint32_t)rst->st_uid ||
	    rst->st_ino == srv->q_ino || est->st_ino == srv->q_ino)
		return MBX_E_ACCESS;
	*pid_rc = pid_check(r->pid, r->uid);
	if (*pid_rc == 0 || *pid_rc == -ESRCH)
		return MBX_E_ACCESS; /* not the owner's process */
	return 0;
}

/* The registration already made for this response queue, if any. Who
 * sends REGISTER is unknown (a message queue has no peer credentials), so
 * a used registration is replaced only by a REGISTER that proves to be
 * that client: it carries the entry's id and token in its header (only
 * the reader of the response queue knows them); otherwise it is refused,
 * unanswered (*refused; a stranger's corr must not complete the victim's
 * call). A registration not confirmed yet is returned: the caller
 * answers it again rather than adding a second one for the same queues. */
static mbx_client *register_existing(mbx_server *srv, const mbx_hdr *h, ino_t resp_ino,
				     bool *refused)
{
	*refused = false;
	for (unsigned i = 0; i < srv->cfg.max_clients; i++) {
		mbx_client *o = &srv->clients[i];

		if (!o->id || o->resp_ino != resp_ino)
			continue;
		if (h->client == o->id && h->token == o->token) {
			client_remove(srv, o, false);
			return NULL;
		}
		if (o->confirmed) {
			count_bad(srv, MBX_BAD_CLIENT);
			*refused = true;
			return NULL;
		}
		return o;
	}
	return NULL;
}

/* A legitimate client confirms its registration as soon as it has read
 * the answer; one still unconfirmed after this long may give its slot to
 * a new registration (it may well be somebody else's REGISTER naming
 * queues their owner does not use on this line). */
static uint64_t confirm_grace_us(const mbx_server *srv)
{
	uint64_t half = (uint64_t)srv->cfg.register_timeout_ms * 500u;

	return half < 1000000u ? half : 1000000u;
}

/* The oldest registration past its confirm grace, of uid only when
 * of_uid: NULL if none. */
static mbx_client *stale_unconfirmed(const mbx_server *srv, bool of_uid, uint32_t uid)
{
	mbx_client *old = NULL;

	for (unsigned i = 0; i < srv->cfg.max_clients; i++) {
		mbx_client *c = &srv->clients[i];

		if (!c->id || c->confirmed || (of_uid && c->uid != uid) ||
		    srv->now_us < c->registered_us + confirm_grace_us(srv))
			continue;
		if (!old || c->registered_us < old->registered_us)
			old = c;
	}
	return old;
}

/* A free slot for a client of uid with access, or NULL (*status
 * MBX_E_FULL): one user cannot take every slot, and the last write_reserve
 * slots are for writers: a read-only client flooding REGISTER must not
 * lock a writer out with FULL. Where a limit is reached, the oldest
 * registration still unconfirmed past its grace (of that user, for the
 * per-user limit) gives way. */
static mbx_client *register_slot(mbx_server *srv, uint32_t uid, uint8_t access, int *status)
{
	for (unsigned pass = 0; pass < 2; pass++) {
		unsigned free_slots = 0, of_uid = 0;
		mbx_client *c = NULL;

		for (unsigned i = 0; i < srv->cfg.max_clients; i++) {
			if (!srv->clients[i].id) {
				if (!c)
					c = &srv->clients[i];
				free_slots++;
			} else if (srv->clients[i].uid == uid) {
				of_uid++;
			}
		}
		bool uid_full = uid != 0 && of_uid >= srv->cfg.max_clients_per_uid;
		bool no_room = !c ||
			       (access < MBX_ACCESS_WRITE && free_slots <= srv->cfg.write_reserve);

		if (!uid_full && !no_room)
			return c;
		mbx_client *old = pass == 0 ? stale_unconfirmed(srv, uid_full, uid) : NULL;

		if (!old)
			break;
		client_remove(srv, old, true);
	}
	srv->stats.limited++;
	*status = MBX_E_FULL;
	return NULL;
}

static void client_init(mbx_server *srv, mbx_client *c, const mbx_register_req *r,
			const reg_queues *q, uint8_t access, int pid_rc)
{
	if (++srv->gen == 0)
		srv->gen = 1;
	memset(c, 0, sizeof *c);
	c->id = ((uint32_t)srv->gen << 16) | (uint32_t)(c - srv->clients + 1);
	c->token = new_token(srv);
	c->resp = q->resp;
	c->evt = q->evt;
	c->resp_msg = (size_t)q->rattr.mq_msgsize;
	c->evt_msg = (size_t)q->eattr.mq_msgsize;
	if (c->resp_msg > MBX_MSG_MAX)
		c->resp_msg = MBX_MSG_MAX;
	if (c->evt_msg > MBX_MSG_MAX)
		c->evt_msg = MBX_MSG_MAX;
	c->resp_depth = (unsigned)q->rattr.mq_maxmsg;
	c->resp_ino = q->rst.st_ino;
	c->evt_ino = q->est.st_ino;
	c->uid = (uint32_t)q->rst.st_uid;
	c->pid = r->pid;
	c->pid_proven = pid_rc == 1;
	c->access = access;
	c->registered_us = srv->now_us;
	lease_renew(srv, c, srv->now_us);
	memcpy(c->resp_name, r->resp_queue, MBX_QNAME_MAX);
	memcpy(c->evt_name, r->event_queue, MBX_QNAME_MAX);
	srv->stats.clients++;
	srv->stats.clients_registered++;
	srv->stats.commands_ok++;
}

/* Open both queues named by the request; false (counted, refused where
 * an answer may go) when either cannot be a client queue. */
static bool register_open_queues(mbx_server *srv, const mbx_hdr *h, const mbx_register_req *r,
				 reg_queues *q)
{
	int status;

	q->resp = open_client_queue(srv, r->resp_queue, &q->rst, &q->rattr, &status);
	if (q->resp == (mqd_t)-1) {
		/* nowhere to answer (or must not answer: readable by all) */
		count_bad(srv, MBX_BAD_QUEUE);
		srv->stats.reg_refused++;
		if (status == MBX_E_ACCESS)
			srv->stats.access_denied++;
		return false;
	}
	q->evt = open_client_queue(srv, r->event_queue, &q->est, &q->eattr, &status);
	if (q->evt == (mqd_t)-1) {
		count_bad(srv, MBX_BAD_QUEUE);
		register_refuse(srv, q, h, status, true);
		mq_close(q->resp);
		return false;
	}
	return true;
}

/* The answer that carries the token (NO_REPLY does not apply to it). */
static int register_answer(mbx_server *srv, mbx_client *c, const mbx_hdr *h)
{
	mbx_register_resp out = {
		.token = c->token,
		.client = c->id,
		.lease_ms = srv->cfg.lease_ms,
		.max_msg = srv->cfg.msg_size,
		.max_transfer = srv->cfg.max_transfer,
		.access = c->access,
		.line = srv->cfg.line,
	};

	c->answered_us = srv->now_us;
	return send_status(srv, c, h->code, h->corr, 0, 0, &out, sizeof out);
}

/* Another REGISTER for the queues of a registration not confirmed yet:
 * the same answer (id, token) again, never a second entry, so repeating a
 * user's REGISTER takes no more of that user's quota than the user's own
 * does. At most once per REG_ANSWER_INTERVAL_US (the rest counted). A
 * REGISTER naming another pid makes the pid worthless for liveness and
 * for removing the queues after the client's death. */
static void register_answer_again(mbx_server *srv, mbx_client *c, const mbx_hdr *h,
				  const mbx_register_req *r)
{
	if (r->pid != c->pid)
		c->pid_disputed = true;
	if (srv->now_us < c->answered_us + REG_ANSWER_INTERVAL_US) {
		srv->stats.reg_unanswered++;
		return;
	}
	register_answer(srv, c, h);
}

static void handle_register(mbx_server *srv, const mbx_hdr *h, const uint8_t *p)
{
	mbx_register_req r;
	reg_queues q;
	mbx_client *c;
	int status, pid_rc;
	uint8_t access;
	bool used;

	memcpy(&r, p, sizeof r);
	if (!register_open_queues(srv, h, &r, &q))
		return;
	status = register_identity(srv, &r, &q.rst, &q.est, &pid_rc);
	if (status) {
		register_refuse(srv, &q, h, status, false);
		goto close;
	}
	c = register_existing(srv, h, q.rst.st_ino, &used);
	if (used) {
		register_refuse(srv, &q, h, MBX_E_ACCESS, false);
		goto close;
	}
	if (c) {
		register_answer_again(srv, c, h, &r);
		goto close;
	}
	access = access_of(srv, (uint32_t)q.rst.st_uid);
	if (access == MBX_ACCESS_NONE)
		status = MBX_E_ACCESS;
	else
		c = register_slot(srv, (uint32_t)q.rst.st_uid, access, &status);
	if (status) {
		register_refuse(srv, &q, h, status, true);
		goto close;
	}
	client_init(srv, c, &r, &q, access, pid_rc);
	if (register_answer(srv, c, h) < 0)
		client_remove(srv, c, true);
	return;
close:
	mq_close(q.resp);
	mq_close(q.evt);
}

static void handle_protocol(mbx_server *srv, mbx_client *c, const mbx_hdr *h, const uint8_t *p)
{
	bool reply = !(h->flags & MBX_F_NO_REPLY);

	srv->stats.commands_ok++;
	switch (h->code) {
	case MBX_CMD_UNREGISTER:
		if (reply)
			send_status(srv, c, h->code, h->corr, 0, 0, NULL, 0);
		client_remove(srv, c, false);
		return;
	case MBX_CMD_SUBSCRIBE: {
		mbx_subscribe_req r;
		mbx_subscribe_resp out;

		memcpy(&r, p, sizeof r);
		c->classes |= r.classes & MBX_EVC_ALL;
		if (r.classes & MBX_EVC_RAW) {
			c->n_filters = r.n_filters;
			memcpy(c->filters, r.filters, sizeof c->filters);
		}
		sub_index_update(srv, c);
		out.classes = c->classes | MBX_EVC_OVERFLOW;
		if (reply)
			send_status(srv, c, h->code, h->corr, 0, 0, &out, sizeof out);
		return;
	}
	case MBX_CMD_UNSUBSCRIBE: {
		mbx_unsubscribe_req r;
		mbx_subscribe_resp out;

		memcpy(&r, p, sizeof r);
		c->classes &= ~r.classes;
		if (r.classes & MBX_EVC_RAW) {
			c->n_filters = 0;
			memset(c->filters, 0, sizeof c->filters);
		}
		sub_index_update(srv, c);
		out.classes = c->classes | MBX_EVC_OVERFLOW;
		if (reply)
			send_status(srv, c, h->code, h->corr, 0, 0, &out, sizeof out);
		return;
	}
	case MBX_CMD_PING: {
		mbx_ping_resp out = { .lease_ms = srv->cfg.lease_ms, .now_us = srv->now_us };

		if (reply)
			send_status(srv, c, h->code, h->corr, 0, 0, &out, sizeof out);
		return;
	}
	case MBX_CMD_XFER_ACK: {
		mbx_xfer_ack r;
		mbx_xfer *x = xfer_find(srv, c->id, h->corr, XS_OUT);

		memcpy(&r, p, sizeof r);
		/* An ack for a finished transfer is normal (the last chunks
		 * raced it); an ack beyond what was sent is ignored. */
		if (x && r.next_chunk > x->acked && r.next_chunk <= x->next_chunk) {
			x->acked = r.next_chunk;
			xfer_pump(srv, x);
		}
		return;
	}
	case MBX_CMD_MBX_STATS: {
		mbx_stats_wire out = {
			.commands_ok = srv->stats.commands_ok,
			.malformed = srv->stats.malformed_total,
			.access_denied = srv->stats.access_denied,
			.events_sent = srv->stats.events_sent,
			.responses_sent = srv->stats.responses_sent,
			.dropped = srv->stats.dropped,
			.clients_registered = srv->stats.clients_registered,
			.clients_reaped = srv->stats.clients_reaped,
			.clients = srv->stats.clients,
			.xfer_failed = srv->stats.xfer_failed,
			.xfer_expired = srv->stats.xfer_expired,
			.limited = srv->stats.limited,
			/* the budget is one for all lines: so are its counts
			 * (SDO uploads of the lines included) */
			.budget_refused = srv->cfg.budget ? atomic_load(&srv->cfg.budget->refused)
							  : srv->stats.budget_refused,
			.budget_used = mbx_budget_used(srv->cfg.budget),
			.late_wakes = srv->stats.late_wakes,
			.reg_refused = srv->stats.reg_refused,
			.reg_unanswered = srv->stats.reg_unanswered,
		};
		if (reply)
			send_status(srv, c, h->code, h->corr, 0, 0, &out, sizeof out);
		return;
	}
	}
}

/* ---- chunked commands ---------------------------------------------------------------- */

static void refuse_transfer(mbx_server *srv, mbx_client *c, const mbx_hdr *h, int status)
{
	srv->stats.xfer_failed++;
	if (h->flags & MBX_F_MORE) {
		c->discarding = true;
		c->discard_corr = h->corr;
	}
	if (!(h->flags & MBX_F_NO_REPLY))
		send_status(srv, c, h->code, h->corr, status, 0, NULL, 0);
}

static void handle_chunk(mbx_server *srv, mbx_client *c, const mbx_hdr *h, const uint8_t *p)
{
	const mbx_cmd_info *ci = mbx_cmd_lookup(h->code);
	mbx_xfer *x;

	if (h->chunk == 0) {
		if (h->total > srv->cfg.max_transfer) {
			refuse_transfer(srv, c, h, MBX_E_TOO_BIG);
			return;
		}
		if (xfer_find(srv, c->id, h->corr, XS_IN)) {
			count_bad(srv, MBX_BAD_SEQUENCE);
			refuse_transfer(srv, c, h, MBX_E_SEQUENCE);
			return;
		}
		int st;

		x = xfer_alloc(srv, c, h->total, &st);
		if (!x) {
			refuse_transfer(srv, c, h, st);
			return;
		}
		x->st = XS_IN;
		x->client = c->id;
		x->corr = h->corr;
		x->code = h->code;
		x->hflags = h->flags;
		x->fixed_len = ci->fixed;
		memcpy(x->fixed, p, ci->fixed);
		x->total = h->total;
		x->done = h->len - ci->fixed;
		xfer_touch(x, x->total);
		memcpy(x->buf, p + ci->fixed, x->done);
		x->next_chunk = 1;
		x->deadline_us = srv->now_us + (uint64_t)srv->cfg.xfer_timeout_ms * 1000u;
		return;
	}
	x = xfer_find(srv, c->id, h->corr, XS_IN);
	if (!x || x->code != h->code || x->next_chunk != h->chunk || x->total != h->total ||
	    x->done + h->len > x->total ||
	    (!(h->flags & MBX_F_MORE) && x->done + h->len != x->total)) {
		count_bad(srv, MBX_BAD_SEQUENCE);
		if (x) {
			srv->stats.xfer_failed++;
			xfer_free(srv, x);
		}
		if (h->flags & MBX_F_MORE) {
			c->discarding = true;
			c->discard_corr = h->corr;
		}
		if (!(h->flags & MBX_F_NO_REPLY))
			send_status(srv, c, h->code, h->corr, MBX_E_SEQUENCE, 0, NULL, 0);
		return;
	}
	memcpy(x->buf + x->done, p, h->len);
	x->done += h->len;
	x->next_chunk++;
	x->deadline_us = srv->now_us + (uint64_t)srv->cfg.xfer_timeout_ms * 1000u;
	if (h->flags & MBX_F_MORE)
		return;
	srv->stats.xfer_in++;
	x->st = XS_HELD;
	mbx_hdr first = *h;

	first.flags = x->hflags;
	dispatch(srv, c, &first, x->fixed, x->fixed_len, x->buf, x->total, x);
}

/* ---- receiving ---------------------------------------------------------------------- */

/* The header checks every command passes first: 0 or a status, *bad the
 * reason. */
static int check_header(const mbx_server *srv, const uint8_t *buf, size_t n, mbx_hdr *h,
			mbx_bad *bad)
{
	int rc = mbx_hdr_decode(buf, n, h, bad);

	if (rc == 0 && h->kind != MBX_KIND_COMMAND) {
		*bad = MBX_BAD_KIND;
		return MBX_E_MALFORMED;
	}
	if (rc == 0 && h->line != srv->cfg.line) {
		*bad = MBX_BAD_LINE;
		return MBX_E_BAD_LINE;
	}
	return rc;
}

/* The sender, authenticated by its token; NULL when unknown, or when the
 * header is too broken to name one. Only an authenticated sender gets an
 * answer, even an error answer: a forged client id must not make us write
 * to somebody else's queue. */
static mbx_client *sender_of(const mbx_server *srv, const mbx_hdr *h, mbx_bad bad)
{
	mbx_client *c;

	if (bad == MBX_BAD_SHORT || bad == MBX_BAD_MAGIC)
		return NULL;
	c = client_find(srv, h->client);
	return c && c->token == h->token ? c : NULL;
}

/* A chunk of a transfer already refused: ignored (the last one ends it). */
static bool discarded(mbx_client *c, const mbx_hdr *h)
{
	if (!c->discarding || c->discard_corr != h->corr || !(h->flags & MBX_F_CHUNKED) ||
	    h->chunk == 0)
		return false;
	if (!(h->flags & MBX_F_MORE))
		c->discarding = false;
	return true;
}

/* A command of c refused with status: the rest of its transfer (when this
 * is the first of several chunks) is ignored, and the client is told when
 * tell and it did not ask for no reply. */
static void refuse_command(mbx_server *srv, mbx_client *c, const mbx_hdr *h, int status, bool tell)
{
	if ((h->flags & MBX_F_MORE) && h->chunk == 0) {
		c->discarding = true;
		c->discard_corr = h->corr;
	}
	if (tell && !(h->flags & MBX_F_NO_REPLY))
		send_status(srv, c, h->code, h->corr, status, 0, NULL, 0);
}

/* Validation, access and the request's own timeout: 0 when c may run the
 * command, else a status (refused and counted here). */
static int admit(mbx_server *srv, mbx_client *c, const mbx_hdr *h, const uint8_t *p)
{
	mbx_bad bad = MBX_BAD_NONE;
	int rc = mbx_cmd_validate(h, p, &bad);

	if (rc) {
		count_bad(srv, bad);
		refuse_command(srv, c, h, rc, true);
		return rc;
	}
	if ((mbx_cmd_lookup(h->code)->flags & MBX_CI_WRITE) && c->access < MBX_ACCESS_WRITE) {
		srv->stats.access_denied++;
		refuse_command(srv, c, h, MBX_E_ACCESS, h->chunk == 0);
		return MBX_E_ACCESS;
	}
	if ((!(h->flags & MBX_F_CHUNKED) || h->chunk == 0) && timeout_too_long(srv, h, p)) {
		count_bad(srv, MBX_BAD_PARAM);
		refuse_command(srv, c, h, MBX_E_PARAM, true);
		return MBX_E_PARAM;
	}
	return 0;
}

/* An admitted command to where it is handled. */
static void run_command(mbx_server *srv, mbx_client *c, const mbx_hdr *h, const uint8_t *p)
{
	const mbx_cmd_info *ci = mbx_cmd_lookup(h->code);

	if (h->flags & MBX_F_CHUNKED)
		handle_chunk(srv, c, h, p);
	else if (ci->flags & MBX_CI_SERVER)
		handle_protocol(srv, c, h, p);
	else if (ci->flags & MBX_CI_DATA)
		dispatch(srv, c, h, p, ci->fixed, p + ci->fixed, h->len - ci->fixed, NULL);
	else
		dispatch(srv, c, h, p, h->len, NULL, 0, NULL);
}

static void handle_msg(mbx_server *srv, const uint8_t *buf, size_t n)
{
	mbx_hdr h;
	mbx_bad bad = MBX_BAD_NONE;
	const uint8_t *p = buf + MBX_HDR_SIZE;
	int rc = check_header(srv, buf, n, &h, &bad);
	mbx_client *c;

	if (rc == 0 && h.code == MBX_CMD_REGISTER) {
		rc = mbx_cmd_validate(&h, p, &bad);
		if (rc) {
			count_bad(srv, bad); /* no queue to answer to */
			srv->stats.reg_refused++;
		} else {
			handle_register(srv, &h, p);
		}
		return;
	}
	c = sender_of(srv, &h, bad);
	if (rc) {
		count_bad(srv, bad);
		if (c && !(h.flags & MBX_F_NO_REPLY))
			send_status(srv, c, h.code, h.corr, rc, 0, NULL, 0);
		return;
	}
	if (!c) {
		count_bad(srv, MBX_BAD_CLIENT);
		return;
	}
	c->confirmed = true;
	lease_renew(srv, c, srv->now_us);
	if (discarded(c, &h) || admit(srv, c, &h, p) != 0)
		return;
	run_command(srv, c, &h, p);
}

int mbx_server_poll(mbx_server *srv, uint64_t now_us)
{
	int n = 0;

	srv->now_us = now_us;
	while ((unsigned)n < srv->cfg.poll_budget) {
		ssize_t r = mq_receive(srv->q, (char *)srv->rx, srv->rx_size, NULL);

		if (r < 0) {
			if (errno == EAGAIN)
				break;
			if (errno == EINTR)
				continue;
			return -errno;
		}
		n++;
		handle_msg(srv, srv->rx, (size_t)r);
	}
	return n;
}

/* ---- answering ---------------------------------------------------------------------- */

static int respond(mbx_server *srv, const mbx_reply_to *to, int status, uint32_t abort,
		   const void *payload, size_t len);

int mbx_server_respond(mbx_server *srv, const mbx_reply_to *to, int status, uint32_t abort,
		       const void *payload, size_t len)
{
	mbx_xfer *x, *held = NULL;
	int rc;

	if (to->slot && to->slot <= srv->cfg.xfer_slots) {
		x = &srv->xfers[to->slot - 1];
		if (x->st == XS_HELD && x->client == to->client && x->corr == to->corr) {
			/* the slot is free again, but payload may live in
			 * its buffer: its pages go back once it is copied */
			held = x;
			xfer_end(srv, x, true);
		}
	}
	rc = respond(srv, to, status, abort, payload, len);
	if (held && held->st == XS_FREE && held->touched > MBX_BUFFER_KEEP) {
		mbx_buffer_release(held->buf, held->touched);
		held->touched = MBX_BUFFER_KEEP;
	}
	return rc;
}

static int respond(mbx_server *srv, const mbx_reply_to *to, int status, uint32_t abort,
		   const void *payload, size_t len)
{
	mbx_client *c;
	mbx_xfer *x;
	size_t nchunks;
	int st;

	c = client_find(srv, to->client);
	if (!c)
		return -ENOENT;
	if (c->outstanding)
		c->outstanding--;
	if (to->flags & MBX_F_NO_REPLY)
		return 0;
	if (len <= chunk_size(c)) {
		int rc = send_status(srv, c, to->code, to->corr, status, abort, payload, len);

		return rc == -EPIPE ? -ENOENT : rc;
	}
	nchunks = (len + chunk_size(c) - 1) / chunk_size(c);
	if (len > srv->cfg.max_transfer || nchunks > 0xFFFFu) {
		srv->stats.xfer_failed++;
		send_status(srv, c, to->code, to->corr, MBX_E_TOO_BIG, 0, NULL, 0);
		return -EMSGSIZE;
	}
	x = xfer_alloc(srv, c, len, &st);
	if (!x) {
		srv->stats.xfer_failed++;
		send_status(srv, c, to->code, to->corr, st, 0, NULL, 0);
		return -EBUSY;
	}
	x->st = XS_OUT;
	x->client = c->id;
	x->corr = to->corr;
	x->code = to->code;
	x->status = status;
	x->abort = abort;
	xfer_touch(x, len);
	memmove(x->buf, payload, len);
	x->total = len;
	x->done = 0;
	x->next_chunk = 0;
	x->acked = 0;
	x->deadline_us = srv->now_us + (uint64_t)srv->cfg.xfer_timeout_ms * 1000u;
	xfer_pump(srv, x);
	return 0;
}

/* A subscriber of the class: does a raw frame pass its filters? */
static bool raw_passes(const mbx_client *c, uint32_t cls, const uint8_t *payload, size_t len)
{
	mbx_ev_raw raw;

	if (cls != MBX_EVC_RAW || c->n_filters == 0)
		return true;
	if (len < sizeof raw)
		return false;
	memcpy(&raw, payload, sizeof raw);
	for (unsigned i = 0; i < c->n_filters; i++)
		if (mbx_raw_filter_match(&c->filters[i], &raw.frame))
			return true;
	return false;
}

/* The event in srv->tx (n bytes, payload len) to one client. */
static bool publish_to(mbx_server *srv, mbx_client *c, uint32_t cls, size_t n, size_t len)
{
	const uint8_t *payload = srv->tx + MBX_HDR_SIZE;

	if (!c->id || c->dead || !raw_passes(c, cls, payload, len))
		return false;
	if (len > c->evt_msg - MBX_HDR_SIZE) {
		/* cannot fit this client's queue: lost, counted, flagged */
		c->drop_evt++;
		c->dropped++;
		srv->stats.dropped++;
		return false;
	}
	return deliver(srv, c, true, n, SEND_NORMAL) == 0;
}

/* Encoded once for all; the recipients are the set bits of the class's
 * index (every client for an overflow notice). */
int mbx_server_publish(mbx_server *srv, uint16_t ev_code, uint64_t corr, const void *payload,
		       size_t len)
{
	uint32_t cls = mbx_event_class_of(ev_code);
	mbx_hdr h = { .code = ev_code, .corr = corr };
	int reached = 0, n;

	if (!cls || (len && !payload))
		return -EINVAL;
	if (len > MBX_MSG_MAX - MBX_HDR_SIZE)
		return -EMSGSIZE;
	n = encode(srv, true, &h, payload, len);
	if (n < 0)
		return n;
	if (cls == MBX_EVC_OVERFLOW) {
		for (unsigned i = 0; i < srv->cfg.max_clients; i++)
			reached += publish_to(srv, &srv->clients[i], cls, (size_t)n, len);
		return reached;
	}
	const uint64_t *words = &srv->sub_bits[(unsigned)__builtin_ctz(cls) * srv->sub_words];

	for (size_t w = 0; w < srv->sub_words; w++) {
		for (uint64_t bits = words[w]; bits; bits &= bits - 1) {
			size_t slot = w * 64 + (size_t)__builtin_ctzll(bits);

			reached += publish_to(srv, &srv->clients[slot], cls, (size_t)n, len);
		}
	}
	return reached;
}

int mbx_server_notify(mbx_server *srv, const mbx_reply_to *to, uint16_t ev_code,
		      const void *payload, size_t len)
{
	mbx_client *c = client_find(srv, to->client);
	mbx_hdr h = { .code = ev_code, .corr = to->corr };
	int rc;

	if (!c)
		return -ENOENT;
	if (!mbx_event_class_of(ev_code))
		return -EINVAL;
	if (len > c->evt_msg - MBX_HDR_SIZE) {
		/* Never cut an event short (an SDO_DONE used to be truncated
		 * to whatever fitted): it cannot reach this client, which is
		 * counted and flagged like any other lost event. */
		c->drop_evt++;
		c->dropped++;
		srv->stats.dropped++;
		return -EMSGSIZE;
	}
	rc = send_to(srv, c, true, &h, payload, len, SEND_NORMAL);
	return rc == -EPIPE ? -ENOENT : rc;
}

/* ---- time ----------------------------------------------------------------------------- */

static uint64_t min64(uint64_t a, uint64_t b)
{
	return a < b ? a : b;
}

/* A client's silence is judged only by a server that was awake to hear it.
 * Woken late - this thread, the daemon or the whole machine stood still (a
 * paused VM, a stopped process, an overloaded box) - the renewals it missed
 * may simply not have run yet: every lapsed lease and registration window
 * starts again, once per late wake. A client whose process is gone is still
 * dropped by the next full check. */
static void forgive_late_wake(mbx_server *srv, uint64_t now_us)
{
	const uint64_t reg_us = (uint64_t)srv->cfg.register_timeout_ms * 1000u;

	srv->stats.late_wakes++;
	for (unsigned i = 0; i < srv->cfg.max_clients; i++) {
		mbx_client *c = &srv->clients[i];

		if (!c->id)
			continue;
		if (srv->cfg.lease_ms && now_us > c->lease_until)
			lease_renew(srv, c, now_us);
		if (!c->confirmed && now_us > c->registered_us + reg_us)
			c->registered_us = now_us;
	}
}

uint64_t mbx_server_tick(mbx_server *srv, uint64_t now_us)
{
	uint64_t next = UINT64_MAX;
	bool full = now_us >= srv->next_check_us;

	if (srv->wake_by_us != UINT64_MAX && now_us > srv->wake_by_us + LATE_WAKE_US)
		forgive_late_wake(srv, now_us);
	srv->now_us = now_us;
	if (full)
		srv->next_check_us = now_us + (uint64_t)srv->cfg.check_ms * 1000u;

	for (unsigned i = 0; i < srv->cfg.xfer_slots; i++) {
		mbx_xfer *x = &srv->xfers[i];

		if (x->st != XS_IN && x->st != XS_OUT)
			continue;
		if (now_us >= x->deadline_us || now_us >= x->end_us) {
			mbx_client *c = client_find(srv, x->client);

			srv->stats.xfer_failed++;
			srv->stats.xfer_expired++;
			if (c && x->st == XS_IN && !(x->hflags & MBX_F_NO_REPLY))
				send_status(srv, c, x->code, x->corr, MBX_E_TIMEOUT, 0, NULL, 0);
			else if (c) /* an answer was lost: tell the client */
				c->drop_resp++;
			xfer_free(srv, x);
			continue;
		}
		if (x->st == XS_OUT && x->retry_us && now_us >= x->retry_us)
			xfer_pump(srv, x);
		if (x->st == XS_FREE)
			continue;
		next = min64(next, min64(x->deadline_us, x->end_us));
		if (x->st == XS_OUT && x->retry_us)
			next = min64(next, x->retry_us);
	}

	for (unsigned i = 0; i < srv->cfg.max_clients; i++) {
		mbx_client *c = &srv->clients[i];

		if (!c->id)
			continue;
		if (client_is_dead(srv, c, now_us, full)) {
			unlink_orphan_queues(c);
			client_remove(srv, c, true);
			continue;
		}
		if (c->drop_evt || c->drop_resp) {
			/* Tell the client what it lost, as soon as its event
			 * queue has room; both counters travel in it. */
			mbx_ev_overflow ov = { .dropped_events = c->drop_evt,
					       .dropped_responses = c->drop_resp };
			mbx_hdr h = { .code = MBX_EV_OVERFLOW };
			uint32_t dr = c->drop_resp;

			if (send_to(srv, c, true, &h, &ov, sizeof ov, SEND_STREAM) == 0) {
				c->drop_resp -= dr;
			} else {
				next = min64(next, now_us + RETRY_US);
			}
		}
		if (srv->cfg.lease_ms)
			next = min64(next, c->lease_until + 1);
		if (!c->confirmed)
			next = min64(next, c->registered_us +
						   (uint64_t)srv->cfg.register_timeout_ms * 1000u +
						   1);
	}
	if (srv->stats.clients)
		next = min64(next, srv->next_check_us);
	srv->wake_by_us = next;
	return next;
}

/* ---- lifetime ------------------------------------------------------------------------ */

/* The documented default of every limit left 0 in the config. */
static void config_fill_defaults(mbx_server_config *c)
{
	if (!c->queue_mode)
		c->queue_mode = 0620;
	if (!c->depth)
		c->depth = 64;
	if (!c->msg_size)
		c->msg_size = MBX_MSG_DEFAULT;
	if (!c->max_clients)
		c->max_clients = 16;
	if (!c->check_ms)
		c->check_ms = 1000;
	if (!c->register_timeout_ms)
		c->register_timeout_ms = 10000;
	if (!c->xfer_slots)
		c->xfer_slots = 2;
	if (!c->max_transfer)
		c->max_transfer = 1u << 20;
	if (!c->xfer_timeout_ms)
		c->xfer_timeout_ms = 5000;
	if (!c->poll_budget)
		c->poll_budget = c->depth;
	if (!c->max_clients_per_uid)
		c->max_clients_per_uid = c->max_clients / 4 ? c->max_clients / 4 : 1;
	/* at least one slot for writers (a table of 2 or 3 included): the
	 * rule "a reader never makes a writer's REGISTER fail with FULL" */
	if (!c->write_reserve && c->max_clients >= 2)
		c->write_reserve = c->max_clients / 4 ? c->max_clients / 4 : 1;
	if (!c->max_outstanding)
		c->max_outstanding = 16;
	if (!c->read_outstanding)
		c->read_outstanding = 32;
	if (!c->xfer_per_client)
		c->xfer_per_client = c->xfer_slots / 2 ? c->xfer_slots / 2 : 1;
	if (!c->max_request_timeout_ms)
		c->max_request_timeout_ms = 60000;
	if (!c->xfer_max_ms)
		c->xfer_max_ms = 60000;
	/* A client queue others can read leaks the token: never allowed. */
	c->forbidden_client_mode |= 0044;
}

static bool config_is_valid(const mbx_server_config *c)
{
	/* The command queue carries every client's token: only the daemon
	 * may read it (in older daemons, with 0660, any member of the group read the
	 * tokens of other clients and acted with their rights). */
	if (c->queue_mode & ~0777u || c->queue_mode & 0044 ||
	    (c->queue_chown && c->queue_uid != geteuid()))
		return false;
	return c->msg_size >= MBX_MSG_MIN && c->msg_size <= MBX_MSG_MAX &&
	       c->max_clients <= 0xFFFFu && c->xfer_slots <= 255;
}

/* Everything the server will ever use, so that nothing is allocated
 * after create: buffers, the client and transfer tables, room for a
 * reload's access rules (mbx_server_set_rules). */
static int allocate_tables(mbx_server *srv, const mbx_access_rule *rules)
{
	mbx_server_config *c = &srv->cfg;

	srv->rx_size = c->msg_size;
	srv->rx = malloc(srv->rx_size);
	srv->tx = malloc(MBX_MSG_MAX);
	srv->clients = calloc(c->max_clients, sizeof *srv->clients);
	srv->sub_words = (c->max_clients + 63) / 64;
	srv->sub_bits = calloc(32 * srv->sub_words, sizeof *srv->sub_bits);
	srv->xfers = calloc(c->xfer_slots, sizeof *srv->xfers);
	srv->rules_cap = c->n_rules > MBX_SERVER_RULES_MAX ? c->n_rules : MBX_SERVER_RULES_MAX;
	srv->rules = calloc(srv->rules_cap, sizeof *srv->rules);
	if (srv->rules && c->n_rules)
		memcpy(srv->rules, rules, c->n_rules * sizeof *srv->rules);
	if (!srv->rx || !srv->tx || !srv->clients || !srv->sub_bits || !srv->xfers || !srv->rules)
		return -ENOMEM;
	c->rules = srv->rules;
	for (unsigned i = 0; i < c->max_clients; i++)
		srv->clients[i].resp = srv->clients[i].evt = (mqd_t)-1;
	for (unsigned i = 0; i < c->xfer_slots; i++) {
		srv->xfers[i].buf = mbx_buffer_reserve(c->max_transfer);
		if (!srv->xfers[i].buf)
			return -ENOMEM;
	}
	return 0;
}

static int open_command_queue(mbx_server *srv)
{
	const mbx_server_config *c = &srv->cfg;
	struct mq_attr attr = { .mq_maxmsg = c->depth, .mq_msgsize = c->msg_size };
	struct stat qst;

	if (c->unlink_existing)
		mq_unlink(srv->qname);
	srv->q = mq_open(srv->qname, O_CREAT | O_EXCL | O_RDONLY | O_NONBLOCK | O_CLOEXEC,
			 c->queue_mode, &attr);
	if (srv->q == (mqd_t)-1)
		return -errno;
	/* The mode given to mq_open is filtered by the umask: set it
	 * exactly, as the config says. */
	if (fchmod((int)srv->q, c->queue_mode) < 0 ||
	    (c->queue_chown && fchown((int)srv->q, c->queue_uid, c->queue_gid) < 0) ||
	    fstat((int)srv->q, &qst) < 0)
		return -errno;
	srv->q_ino = qst.st_ino;
	return 0;
}

int mbx_server_create(mbx_server **out, const mbx_server_config *cfg)
{
	mbx_server *srv;
	int rc;

	*out = NULL;
	if (!cfg || !cfg->queue_name || cfg->line >= MBX_LINES_MAX ||
	    !mbx_queue_name_is_valid(cfg->queue_name, strlen(cfg->queue_name) + 1) ||
	    (cfg->n_rules && !cfg->rules) || cfg->default_access > MBX_ACCESS_WRITE)
		return -EINVAL;
	srv = calloc(1, sizeof *srv);
	if (!srv)
		return -ENOMEM;
	srv->q = (mqd_t)-1;
	srv->wake_by_us = UINT64_MAX;
	srv->cfg = *cfg;
	config_fill_defaults(&srv->cfg);
	rc = -EINVAL;
	if (!config_is_valid(&srv->cfg))
		goto fail;
	strcpy(srv->qname, cfg->queue_name);
	srv->cfg.queue_name = srv->qname;
	rc = allocate_tables(srv, cfg->rules);
	if (rc)
		goto fail;
	if (getrandom(&srv->rng, sizeof srv->rng, GRND_NONBLOCK) != (ssize_t)sizeof srv->rng)
		srv->rng = (uint64_t)getpid() * 0x9E3779B97F4A7C15ull ^ (uint64_t)(uintptr_t)srv;
	rc = open_command_queue(srv);
	if (rc)
		goto fail;
	*out = srv;
	return 0;
fail:
	mbx_server_destroy(srv);
	return rc;
}

void mbx_server_destroy(mbx_server *srv)
{
	if (!srv)
		return;
	if (srv->clients) {
		for (unsigned i = 0; i < srv->cfg.max_clients; i++) {
			if (srv->clients[i].resp != (mqd_t)-1)
				mq_close(srv->clients[i].resp);
			if (srv->clients[i].evt != (mqd_t)-1)
				mq_close(srv->clients[i].evt);
		}
	}
	if (srv->xfers)
		for (unsigned i = 0; i < srv->cfg.xfer_slots; i++)
			mbx_buffer_free(srv->xfers[i].buf, srv->cfg.max_transfer);
	if (srv->q != (mqd_t)-1) {
		mq_close(srv->q);
		mq_unlink(srv->qname);
	}
	free(srv->xfers);
	free(srv->clients);
	free(srv->sub_bits);
	free(srv->rules);
	free(srv->tx);
	free(srv->rx);
	free(srv);
}

int mbx_server_fd(const mbx_server *srv)
{
	return (int)srv->q;
}

int mbx_server_set_rules(mbx_server *srv, const mbx_access_rule *rules, size_t n_rules,
			 uint8_t default_access)
{
	if (n_rules > srv->rules_cap || (n_rules && !rules) || default_access > MBX_ACCESS_WRITE)
		return -EINVAL;
	if (n_rules)
		memcpy(srv->rules, rules, n_rules * sizeof *srv->rules);
	srv->cfg.n_rules = n_rules;
	srv->cfg.default_access = default_access;
	/* Access is granted at REGISTER; a reload that revokes a right must
	 * reach the clients already registered too, or it would not take
	 * effect until they reconnect. A client left with no access at all
	 * is dropped (it would be refused registration now). */
	for (unsigned i = 0; i < srv->cfg.max_clients; i++) {
		mbx_client *c = &srv->clients[i];

		if (!c->id)
			continue;
		c->access = access_of(srv, c->uid);
		if (c->access == MBX_ACCESS_NONE) {
			srv->stats.access_denied++;
			client_remove(srv, c, true);
		}
	}
	return 0;
}

void mbx_server_set_lease(mbx_server *srv, unsigned lease_ms)
{
	srv->cfg.lease_ms = lease_ms;
	/* Every client gets a full new lease: one computed with the old
	 * value (0 = none) would expire at once. */
	for (unsigned i = 0; i < srv->cfg.max_clients; i++)
		if (srv->clients[i].id)
			lease_renew(srv, &srv->clients[i], srv->now_us);
}

size_t mbx_server_buffer_bytes(const mbx_server *srv)
{
	return (size_t)srv->cfg.xfer_slots * (srv->cfg.max_transfer + sizeof *srv->xfers) +
	       srv->rx_size + MBX_MSG_MAX + srv->cfg.max_clients * sizeof *srv->clients +
	       srv->rules_cap * sizeof *srv->rules;
}

const mbx_server_stats *mbx_server_stats_get(const mbx_server *srv)
{
	return &srv->stats;
}

unsigned mbx_server_subscribers(const mbx_server *srv, uint32_t cls)
{
	unsigned n = 0;

	if (!cls || (cls & (cls - 1)) || cls == MBX_EVC_OVERFLOW)
		return cls == MBX_EVC_OVERFLOW ? (unsigned)srv->stats.clients : 0;
	const uint64_t *words = &srv->sub_bits[(unsigned)__builtin_ctz(cls) * srv->sub_words];

	for (size_t w = 0; w < srv->sub_words; w++)
		n += (unsigned)__builtin_popcountll(words[w]);
	return n;
}

int mbx_server_client_info(const mbx_server *srv, unsigned n, mbx_client_info *info)
{
	for (unsigned i = 0; i < srv->cfg.max_clients; i++) {
		const mbx_client *c = &srv->clients[i];

		if (!c->id || n--)
			continue;
		*info = (mbx_client_info){
			.id = c->id,
			.uid = c->uid,
			.pid = c->pid,
			.access = c->access,
			.confirmed = c->confirmed,
			.classes = c->classes,
			.dropped = c->dropped,
			.pending_drop_events = c->drop_evt,
			.pending_drop_responses = c->drop_resp,
		};
		memcpy(info->resp_queue, c->resp_name, MBX_QNAME_MAX);
		memcpy(info->event_queue, c->evt_name, MBX_QNAME_MAX);
		return 0;
	}
	return -ENOENT;
}

size_t mbx_server_client_max_payload(const mbx_server *srv, uint32_t client)
{
	const mbx_client *c = client_find(srv, client);

	return c ? chunk_size(c) : 0;
}
