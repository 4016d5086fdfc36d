/* SPDX-License-Identifier: MIT */
/*
 * mailbox/server_int.h - what the files of the mailbox server share (the
 * public interface is mailbox/server.h). Include it from mailbox/server*.c
 * only.
 *
 * The files, top to bottom (a file calls only files below it):
 *   server.c           create, destroy, the rules, mbx_server_poll() and
 *                      mbx_server_tick()
 *   server_dispatch.c  one received message: header, token, validation,
 *                      access, limits, then to where it is handled (the
 *                      line's dispatcher for service commands)
 *   server_register.c  REGISTER: queues, owner, rights, pid, token
 *   server_protocol.c  the other commands the mailbox answers itself
 *   server_answer.c    the line's answers (mbx_server_respond)
 *   server_clients.c   a client's lease, death and removal; the client
 *                      table's time
 *   server_events.c    event fan-out (mbx_server_publish, _notify), the
 *                      subscriber index, the overflow notice
 *   server_xfer.c      transfers and chunking: slots, reassembly, streams
 *   server_send.c      finding a client, sending to its queues
 * The line's callbacks (cfg.dispatch) are declared in server.h, where they
 * are taken.
 */
#ifndef COGW_MAILBOX_SERVER_INT_H
#define COGW_MAILBOX_SERVER_INT_H

#include <mqueue.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "mailbox/server.h"

#define RETRY_US 20000u /* resume a chunk stream / overflow notice */
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

enum send_mode {
	SEND_NORMAL, /* a full queue = a dropped message */
	SEND_STREAM, /* a full queue = wait (flow-controlled chunk stream) */
};

static inline uint64_t min64(uint64_t a, uint64_t b)
{
	return a < b ? a : b;
}

/* ---- server_dispatch.c ---------------------------------------------------------- */

/* One message from the command queue (n bytes in buf), answered or
 * dispatched. */
void srv_handle_msg(mbx_server *srv, const uint8_t *buf, size_t n);

/* ---- server_register.c ---------------------------------------------------------- */

/* A valid REGISTER command (h, payload p): registered, refused or answered
 * again. */
void srv_handle_register(mbx_server *srv, const mbx_hdr *h, const uint8_t *p);
/* The access the rules grant user uid (root: write). */
uint8_t srv_access_of(const mbx_server *srv, uint32_t uid);

/* ---- server_protocol.c ---------------------------------------------------------- */

/* An admitted protocol command (MBX_CI_SERVER) of c, other than REGISTER. */
void srv_handle_protocol(mbx_server *srv, mbx_client *c, const mbx_hdr *h, const uint8_t *p);

/* ---- server_clients.c ----------------------------------------------------------- */

/* Free c's entry (reaped: it died, else it unregistered), with its
 * transfers in flight and subscriptions; tells the line (client_gone). */
void srv_client_remove(mbx_server *srv, mbx_client *c, bool reaped);
/* A full lease from now (any command renews it). */
void srv_lease_renew(const mbx_server *srv, mbx_client *c, uint64_t now_us);
/* Woken late: every lapsed lease and registration window starts again. */
void srv_forgive_late_wake(mbx_server *srv, uint64_t now_us);
/* Dead clients removed, overflow notices sent; when the table wants the
 * tick again. full: also check processes and queues. */
uint64_t srv_clients_tick(mbx_server *srv, uint64_t now_us, bool full);

/* ---- server_events.c ------------------------------------------------------------ */

/* Keep the class index of client c in step with c->classes (and c->id:
 * a free slot subscribes to nothing). */
void srv_sub_index_update(mbx_server *srv, const mbx_client *c);
/* Tell c what it lost (both drop counters) when its event queue has room;
 * false while it has none. */
bool srv_overflow_notice(mbx_server *srv, mbx_client *c);

/* ---- server_xfer.c -------------------------------------------------------------- */

/* A chunk of a command of c: the slot once the command is complete
 * (XS_HELD, to be dispatched), else NULL (more to come, or refused and
 * answered here). */
mbx_xfer *srv_chunk_in(mbx_server *srv, mbx_client *c, const mbx_hdr *h, const uint8_t *p);
/* An answer larger than one message: copied into a slot and streamed. */
int srv_stream_answer(mbx_server *srv, mbx_client *c, const mbx_reply_to *to, int status,
		      uint32_t abort, const void *payload, size_t len);
/* Push chunks of an outgoing transfer while the window and queue allow. */
void srv_xfer_pump(mbx_server *srv, mbx_xfer *x);
mbx_xfer *srv_xfer_find(mbx_server *srv, uint32_t client, uint64_t corr, xfer_state st);
/* End a transfer: its budget goes back; its pages too unless keep_pages
 * (the caller still reads the buffer and gives them back itself). */
void srv_xfer_end(mbx_server *srv, mbx_xfer *x, bool keep_pages);
void srv_xfer_free(mbx_server *srv, mbx_xfer *x);
/* Stalled or expired transfers fail, waiting streams resume; when the
 * slots want the tick again. */
uint64_t srv_xfers_tick(mbx_server *srv, uint64_t now_us);
/* The data one message to c carries. */
size_t srv_chunk_size(const mbx_client *c);

/* ---- server_send.c -------------------------------------------------------------- */

/* The registered client with this id, or NULL. */
mbx_client *srv_client_find(const mbx_server *srv, uint32_t id);
void srv_count_bad(mbx_server *srv, mbx_bad b);
/* Encode one message into srv->tx (addressed to nobody yet): its length
 * or -errno. */
int srv_encode(mbx_server *srv, bool event, mbx_hdr *h, const void *payload, size_t len);
/* Send the message in srv->tx (n bytes) to c's response or event queue:
 * 0, -EAGAIN (stream: queue full), -ENOBUFS (dropped), -EPIPE (queue
 * unusable: client marked dead). */
int srv_deliver(mbx_server *srv, mbx_client *c, bool event, size_t n, enum send_mode mode);
/* srv_encode + srv_deliver. */
int srv_send_to(mbx_server *srv, mbx_client *c, bool event, mbx_hdr *h, const void *payload,
		size_t len, enum send_mode mode);
/* An answer with status (and abort, payload) to c's response queue. */
int srv_send_status(mbx_server *srv, mbx_client *c, uint16_t code, uint64_t corr, int status,
		    uint32_t abort, const void *payload, size_t len);

#endif
