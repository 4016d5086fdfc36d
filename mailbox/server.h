/* SPDX-License-Identifier: MIT */
/*
 * mailbox/server.h - the daemon side of the mailbox, ONE INSTANCE PER LINE.
 *
 * Threading: everything here is called by the line thread that owns the
 * server, and only by it. The server owns the line's command queue and a
 * table of the clients registered on this line; no lock is shared with
 * another line (several lines may send to the same client queue, which the
 * kernel serialises). Nothing here blocks: every mq operation is
 * O_NONBLOCK, and nothing allocates after mbx_server_create().
 *
 * Loop integration (the line thread's epoll loop):
 *     epoll on mbx_server_fd(srv) (EPOLLIN)  -> mbx_server_poll(srv, now)
 *     timerfd at min(core deadline, mbx_server_tick(srv, now))
 *     core events                            -> mbx_server_publish()
 *     SDO/LSS/... completions                -> mbx_server_respond()
 *
 * Protocol commands (REGISTER, UNREGISTER, SUBSCRIBE, UNSUBSCRIBE, PING,
 * XFER_ACK, MBX_STATS) and every refusal are answered here. Valid service
 * commands from allowed clients go to cfg.dispatch, which answers later (or
 * at once) with mbx_server_respond() using the request's reply handle.
 *
 * Large data (see docs/mailbox.md "Chunking"):
 *  - client -> daemon: the server reassembles a chunked command into one of
 *    cfg.xfer_slots buffers of cfg.max_transfer bytes (reserved at create,
 *    paid from cfg.budget per transfer, pages beyond MBX_BUFFER_KEEP given
 *    back after it: mailbox/budget.h)
 *    and dispatches it once complete. req->data then stays valid until the
 *    request is answered (so an SDO download can point the SDO client at
 *    it); for a single-message request it is valid only during dispatch.
 *  - daemon -> client: mbx_server_respond() with more data than one message
 *    copies the data into a transfer slot and streams it under flow control
 *    (the client acknowledges with XFER_ACK; the server sends only what the
 *    client queue has room for, never blocks, resumes on ACK or on tick).
 */
#ifndef COGW_MAILBOX_SERVER_H
#define COGW_MAILBOX_SERVER_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "mailbox/budget.h"
#include "mailbox/proto.h"

typedef struct mbx_server mbx_server;

/* Where an answer goes: copy it out of the request, give it back to
 * mbx_server_respond(). Plain data. */
typedef struct mbx_reply_to {
	uint32_t client;
	uint16_t code; /* command code echoed */
	uint8_t flags; /* MBX_F_NO_REPLY if the client asked for no answer */
	uint8_t slot;  /* transfer slot + 1 holding req->data, 0 = none */
	uint64_t corr;
} mbx_reply_to;

/* One valid service command from a client allowed to send it. */
typedef struct mbx_request {
	mbx_reply_to reply;
	uint16_t code; /* enum mbx_cmd */
	uint8_t line;
	uint8_t access;         /* the client's enum mbx_access */
	uint32_t uid;           /* owner of the client's queues */
	uint32_t pid;           /* as registered */
	const uint8_t *payload; /* fixed part (validated), len = fixed_len */
	size_t fixed_len;
	const uint8_t *data; /* trailing data (DATA commands), or NULL */
	size_t data_len;
} mbx_request;

/*
 * The line's service implementation. dispatch() is called from inside
 * mbx_server_poll(); it must not block. It answers with
 * mbx_server_respond() now or later (exactly once per request); a request
 * it cannot serve gets a status such as MBX_E_UNSUPPORTED.
 * client_gone() (optional) tells that a client was removed (unregistered or
 * reaped), so the glue can cancel work it started for it; answers sent
 * afterwards are discarded harmlessly.
 */
typedef struct mbx_dispatch {
	void (*dispatch)(void *ctx, mbx_server *srv, const mbx_request *req);
	void (*client_gone)(void *ctx, mbx_server *srv, uint32_t client);
} mbx_dispatch;

typedef struct mbx_access_rule {
	uint32_t uid;
	uint8_t access; /* enum mbx_access */
} mbx_access_rule;

typedef struct mbx_server_config {
	uint8_t line;           /* < MBX_LINES_MAX */
	const char *queue_name; /* e.g. from mbx_queue_name(); required */
	/* Command queue mode (0 = 0620). Every command carries its client's
	 * token, so no read bit for group/others is allowed (-EINVAL). */
	unsigned queue_mode;
	uid_t queue_uid; /* chown the command queue (with queue_gid) */
	gid_t queue_gid; /*   if queue_chown is set; queue_uid must be
	                         *   the daemon's own (the owner reads it) */
	bool queue_chown;
	unsigned depth;               /* command queue mq_maxmsg (0 = 64) */
	unsigned msg_size;            /* command queue mq_msgsize (0 = 1024) */
	unsigned max_clients;         /* per line (0 = 16) */
	unsigned lease_ms;            /* 0 = no lease: only pid / queue checks */
	unsigned check_ms;            /* liveness check period (0 = 1000) */
	unsigned register_timeout_ms; /* a client that never sends a command
	                               * with its token is dropped (0 = 10000) */
	unsigned xfer_slots;          /* concurrent chunked transfers (0 = 2) */
	unsigned max_transfer;        /* bytes per chunked transfer (0 = 1 MiB) */
	unsigned xfer_timeout_ms;     /* a stalled transfer is dropped (0 = 5000) */
	unsigned poll_budget;         /* messages per mbx_server_poll (0 = depth) */
	/* Per-user and per-client limits (docs/mailbox.md "Security model"):
	 * nothing one client (or one user) does may make another's request
	 * fail with FULL or BUSY. 0 = the default in brackets. */
	unsigned max_clients_per_uid;    /* registrations per uid, root exempt
	                               * (max(1, max_clients / 4)) */
	unsigned write_reserve;          /* client slots only a writer may take
	                          * (max(1, max_clients / 4); 0 with one slot) */
	unsigned max_outstanding;        /* requests of one client dispatched and
	                           * not answered yet (16); more -> BUSY */
	unsigned read_outstanding;       /* all read-only clients together (32) */
	unsigned xfer_per_client;        /* transfer slots of one client
	                           * (max(1, xfer_slots / 2)); read-only
	                           * clients together leave one to writers */
	unsigned max_request_timeout_ms; /* ceiling of a request's own
	                                  * timeout_ms (SDO, LSS) (60000);
	                                  * above -> PARAM */
	unsigned xfer_max_ms;            /* a chunked transfer ends within this,
	                         * however slowly it progresses (60000) */
	/* Transfer memory shared by all lines (NULL = none): a chunked
	 * transfer takes its size before it touches a slot's buffer; refused
	 * (MBX_E_NO_MEMORY) when it does not fit. */
	mbx_budget *budget;
	/* Access: root always gets WRITE; a uid in rules gets its access;
	 * everyone else default_access (NONE = registration refused). */
	const mbx_access_rule *rules;
	size_t n_rules;
	uint8_t default_access;
	/* Mode bits a client queue must NOT have: the token travels in the
	 * response queue, so nobody but its owner may read it. 0044 is always
	 * added (a config can forbid more, never less). */
	unsigned forbidden_client_mode;
	bool unlink_existing; /* remove a stale command queue first */
	mbx_dispatch dispatch;
	void *dispatch_ctx;
} mbx_server_config;

/* Counters (plain data, owner thread). */
typedef struct mbx_server_stats {
	uint64_t commands_ok;              /* valid commands accepted */
	uint64_t malformed[MBX_BAD_COUNT]; /* refused, per reason */
	uint64_t malformed_total;
	uint64_t access_denied; /* registration or write refused */
	uint64_t responses_sent;
	uint64_t events_sent;
	uint64_t dropped; /* messages lost on full client queues */
	uint64_t clients_registered;
	uint64_t clients_unregistered;
	uint64_t clients_reaped;    /* dead, lease expired, unconfirmed */
	uint64_t xfer_in, xfer_out; /* chunked transfers completed */
	uint64_t xfer_failed;       /* timed out, too big, no slot */
	uint64_t xfer_expired;      /* of xfer_failed: stalled, or over the
				     * transfer lifetime */
	uint64_t limited;           /* refused by a per-user/client limit */
	uint64_t budget_refused;    /* refused by the transfer memory budget */
	uint64_t late_wakes;        /* ticks that came too late to judge leases */
	uint64_t reg_refused;       /* REGISTERs refused (any reason) */
	uint64_t reg_unanswered;    /* REGISTERs left unanswered because their
				     * sender may not own the queues they name */
	uint32_t clients;           /* current */
} mbx_server_stats;

/* Public view of one client (mbx_server_client_info). */
typedef struct mbx_client_info {
	uint32_t id;
	uint32_t uid, pid;
	uint8_t access;
	bool confirmed;
	uint32_t classes;
	uint64_t dropped; /* total lost to this client */
	uint32_t pending_drop_events, pending_drop_responses;
	char resp_queue[MBX_QNAME_MAX], event_queue[MBX_QNAME_MAX];
} mbx_client_info;

/*
 * Create the line's command queue (O_CREAT|O_EXCL, O_RDONLY|O_NONBLOCK,
 * explicit depth/msg size) and the fixed pools. Returns 0, -EINVAL (bad
 * config), -EEXIST (queue exists and !unlink_existing), -ENOMEM, or the
 * -errno of mq_open (-EINVAL there usually means the system limits are
 * too low: call mbx_check_system_limits() first for a clear message).
 */
int mbx_server_create(mbx_server **out, const mbx_server_config *cfg);
/* Closes client queues (clients are not told), unlinks the command queue.
 * Accepts NULL. */
void mbx_server_destroy(mbx_server *srv);

/* The command queue descriptor, for epoll (EPOLLIN). */
int mbx_server_fd(const mbx_server *srv);

/* Read and handle pending commands (at most cfg.poll_budget). Returns the
 * number of messages read (>= 0) or -errno of mq_receive. */
int mbx_server_poll(mbx_server *srv, uint64_t now_us);

/* Leases, dead clients, stalled transfers, pending overflow notices,
 * resumed chunk streams. Returns the absolute time of the next call
 * (UINT64_MAX if nothing is pending). */
uint64_t mbx_server_tick(mbx_server *srv, uint64_t now_us);

/*
 * Answer a request. status 0 or a negative mbx_status; abort a CiA abort
 * code (with MBX_E_ABORT) or 0; payload any size up to cfg.max_transfer
 * (chunked when larger than one message). Releases the transfer slot that
 * held the request's data. Returns 0; -ENOENT if the client is gone (the
 * answer is discarded); -ENOBUFS if the answer was dropped (client queue
 * full: counted and flagged); -EBUSY if it needed a transfer slot and none
 * was free (the client got MBX_E_BUSY instead); -EMSGSIZE if larger than
 * max_transfer (the client got MBX_E_TOO_BIG).
 */
int mbx_server_respond(mbx_server *srv, const mbx_reply_to *to, int status, uint32_t abort,
		       const void *payload, size_t len);

/*
 * Fan an event out to every client of this line subscribed to its class
 * (overflow notices to everyone). corr: the request it belongs to, or 0.
 * Events are never chunked: one that does not fit a client's event queue
 * messages is dropped for that client (counted and flagged). Raw frames are matched against each client's filters. Returns the number
 * of clients it reached, or -EINVAL / -EMSGSIZE.
 */
int mbx_server_publish(mbx_server *srv, uint16_t ev_code, uint64_t corr, const void *payload,
		       size_t len);
/* Send one event to the client of a request (whatever its subscriptions):
 * asynchronous events that belong to a request. An event larger than the
 * client's event messages is not sent (never truncated): dropped, counted
 * and flagged, -EMSGSIZE. Returns 0, -ENOENT, -ENOBUFS, -EMSGSIZE. */
int mbx_server_notify(mbx_server *srv, const mbx_reply_to *to, uint16_t ev_code,
		      const void *payload, size_t len);

/*
 * Reload (SIGHUP) of the access settings, on the owner thread: replace the
 * rules (at most MBX_SERVER_RULES_MAX, or the create-time count if larger)
 * and default_access. Registered clients are re-evaluated at once: their
 * level follows the new rules, and a client left with MBX_ACCESS_NONE is
 * dropped (reaped; client_gone is called). Returns 0 or -EINVAL.
 */
#define MBX_SERVER_RULES_MAX 64u
int mbx_server_set_rules(mbx_server *srv, const mbx_access_rule *rules, size_t n_rules,
			 uint8_t default_access);
/* New lease (0 = none); every registered client's lease restarts now. */
void mbx_server_set_lease(mbx_server *srv, unsigned lease_ms);

const mbx_server_stats *mbx_server_stats_get(const mbx_server *srv);
/* Bytes reserved at create for buffers and tables (transfer slots of
 * max_transfer bytes each - address space, see mailbox/budget.h -,
 * message buffers, client table). */
size_t mbx_server_buffer_bytes(const mbx_server *srv);
/* Info about the n-th live client (0-based); -ENOENT past the end. */
int mbx_server_client_info(const mbx_server *srv, unsigned n, mbx_client_info *info);

/* How many clients subscribed to event class cls (one MBX_EVC_* bit):
 * a count of the class's subscriber bitmap, not a walk of the clients. */
unsigned mbx_server_subscribers(const mbx_server *srv, uint32_t cls);
/* Largest payload a response/event to this client can carry in one
 * message (the smaller of the line's and the client queue's size). */
size_t mbx_server_client_max_payload(const mbx_server *srv, uint32_t client);

#endif /* COGW_MAILBOX_SERVER_H */
