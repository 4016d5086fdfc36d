/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-ascii/gateway.h - the CiA 309-3 ASCII gateway process: its
 * connections (server.c: sockets, the epoll loop, line framing, output
 * back-pressure), their commands (session.c: a command's mailbox request
 * and its answer in one place) and their output buffers (output.c). One
 * thread; nothing here blocks on a peer. Reference: docs/ascii.md.
 *
 * Calls go down only: main.c -> server.c -> session.c -> output.c
 * (tests/checks/check_callgraph).
 */
#ifndef COGW_ASCII_GATEWAY_H
#define COGW_ASCII_GATEWAY_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "apps/cogw-ascii/ascii_config.h"
#include "apps/cogw-ascii/ascii_parse.h"
#include "apps/common/config.h"
#include "mailbox/cogw.h"

#define GW_VERSION "cogw-ascii 1.0 (CiA 309-3 DS 2.1 command set, docs/ascii.md)"

struct conn;

/* One command of a connection, from its line to its answer. Allocated per
 * command; when its connection goes away while the mailbox request is
 * under way, it stays (conn NULL) until the daemon's answer frees it, so
 * no transfer slot of the daemon is left behind unaccounted. */
typedef struct request {
	struct request *next_wait; /* waiting for a mailbox slot of its line */
	struct conn *conn;
	ascii_cmd cmd;
	uint16_t net;     /* resolved network */
	uint8_t node;     /* resolved node */
	unsigned line;    /* the daemon line asked */
	uint16_t mbx_cmd; /* MBX_CMD_* to send */
	uint8_t *payload; /* fixed part + data */
	size_t payload_len;
	uint64_t corr;  /* 0 = not sent */
	bool in_flight; /* sent, reply not yet here */
	bool waiting;   /* in the wait queue */
	bool large;     /* its data may take more than one mailbox message */
	bool done;      /* answer is set */
	char *answer;   /* answer text with line ends, NUL-terminated */
	size_t answer_len;
} request;

typedef struct conn {
	struct conn *next;
	int fd;
	unsigned id;
	bool tcp;
	uid_t uid;
	pid_t pid;
	uint8_t access; /* cogw_access_level */
	char *in;       /* bytes of the line being received */
	size_t in_len;
	bool discarding; /* an overlong line: skip to its end */
	char *out;       /* answers not yet written */
	size_t out_len, out_off, out_cap;
	request **slots; /* commands under way, in arrival order (ring) */
	unsigned head, count;
	int net, node; /* defaults, -1 = not set */
	unsigned sdo_timeout_ms;
	bool sdo_block;
	uint32_t events; /* ASCII_EV_* wanted */
	bool reading;    /* EPOLLIN armed */
	bool writing;    /* EPOLLOUT armed */
	bool eof;        /* the peer closed its side: close when answered */
	bool dead;       /* close now */
	bool kick;       /* something changed: the loop pumps it */
	bool slow;       /* its unread answers reached max_output */
} conn;

typedef struct gw_stats {
	uint64_t accepted, refused_full, refused_access, closed;
	uint64_t commands, syntax_errors, denied, overlong, slow_readers;
	uint64_t mbx_errors, orphaned, expired;
} gw_stats;

/* The depth of our response queue: as many requests under way in all
 * (main.c opens the handle with it). */
#define GW_RESP_DEPTH 64u

/* A line whose command queue had no room (session.c sends, server.c waits). */
enum gw_line_room {
	GW_FREE,    /* sends go */
	GW_BLOCKED, /* refused: wait until its command queue is writable */
	GW_ROOM,    /* writable again: try */
	GW_AGAIN    /* refused although writable (the line registers again after a daemon
		     * restart, or another client was quicker): try at the next wake-up,
		     * RETRY_PAUSE_MS at the latest */
};

typedef struct gateway {
	ascii_config cfg;
	cogw_config daemon;
	cogw *h;
	int epfd, sigfd;
	int listen_fd[8];
	bool listen_tcp[8];
	unsigned n_listen;
	conn *conns;
	unsigned n_conns, next_id;
	request *wait_head, *wait_tail;          /* requests waiting for a mailbox slot */
	unsigned inflight[COGW_LINES_MAX];       /* mailbox requests under way per line */
	unsigned inflight_max;                   /* the daemon's max_outstanding */
	unsigned inflight_total;                 /* of every line */
	uint8_t blocked[COGW_LINES_MAX];         /* enum gw_line_room */
	int armed_fd[COGW_LINES_MAX];            /* command queue watched for room, or -1 */
	unsigned large_inflight[COGW_LINES_MAX]; /* of them large (0 or 1) */
	request **sent;                          /* requests under way (by corr) */
	size_t n_sent, cap_sent;
	uint32_t subscribed[COGW_LINES_MAX];
	gw_stats st;
	bool stop;
	int verbose;
	char daemon_config_path[256]; /* "" = cogwd's embedded default */
} gateway;

/* session.c */
/* A complete line of conn (without its line end) arrived. */
void session_line(gateway *g, conn *c, const char *line, size_t len);
/* Answer ERROR: err in c's turn, for input that is no command (an
 * overlong line). */
void session_refuse(gateway *g, conn *c, int err);
/* A mailbox answer or event from cogw_loop_recv (a request libcogw gave
 * up on after request_timeout_ms comes as COGW_E_TIMEOUT: ERROR: 103). */
void session_mailbox(gateway *g, const cogw_msg *m);
/* The connection goes: its requests under way become orphans. */
void session_conn_gone(gateway *g, conn *c);
/* Send what waits for a mailbox slot, in order per line (after an answer,
 * a command queue's room, a pause). */
void session_launch(gateway *g);
/* At exit, after every connection closed: free what is left. */
void session_free_all(gateway *g);
/* Line of network net (the daemon's), or -1 if not attached. */
int session_line_of_net(const gateway *g, unsigned net);

/* server.c */
int server_run(gateway *g);

/* output.c */
/* Bytes queued for c and not yet written. */
size_t conn_pending_out(const conn *c);
/* Queue text for c (flushed by the loop). False: the peer is not reading
 * and its output limit is reached: it is dropped. */
bool conn_write(conn *c, const char *text, size_t len);

#endif /* COGW_ASCII_GATEWAY_H */
