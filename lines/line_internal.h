/* SPDX-License-Identifier: MIT */
/*
 * lines/line_internal.h - the line object, shared by the files of lines/
 * (line.c: thread and loop; line_events.c: core events -> mailbox events;
 * line_cmds.c: mailbox commands -> core calls; line_store.c: persistence).
 * Everything here belongs to the line thread unless marked atomic.
 */
#ifndef COGW_LINES_LINE_INTERNAL_H
#define COGW_LINES_LINE_INTERNAL_H

#include <pthread.h>
#include <stdatomic.h>

#include "lines/line.h"

#define LINE_NODES 128
#define LINE_PENDING_MAX 64 /* mailbox requests waiting for the core */
#define LINE_BIG_SLOTS 4    /* of which with a max_transfer buffer */
#define LINE_INLINE_MAX 1024

/* What only the line counts about a remote node; states, supervision and
 * times come from the heartbeat consumer (core/heartbeat.h). */
typedef struct line_node_info {
	uint32_t bootups;
	uint16_t last_emcy;
	uint32_t emcy_count;
} line_node_info;

/* A mailbox request waiting for an asynchronous core completion. */
typedef struct line_pending {
	bool used;
	uint16_t code;      /* mailbox command */
	uint64_t tag;       /* core tag (unique per line) */
	mbx_reply_to reply;
	uint8_t *buf;       /* big upload/download buffer, slots 0..3 only */
	uint32_t cap;
	uint8_t inline_data[LINE_INLINE_MAX]; /* small download copied here */
} line_pending;

/* Storage hand-off to the main thread (1010h "save", 1011h "load"). */
typedef struct line_store_req {
	atomic_int state;   /* 0 idle, 1 requested (main works), 2 done */
	int result;         /* 0 or -errno, written by main before state=2 */
	uint8_t op;         /* 1 save, 2 restore (delete) */
	uint8_t sub;        /* 1 all, 2 communication, 3 application */
	bool from_sdo;      /* answer: SDO server channel, else mailbox */
	uint8_t channel;    /* SDO server channel waiting */
	mbx_reply_to reply; /* mailbox request waiting */
	uint32_t len;
	uint8_t *blob;      /* serialised values, LINE_STORE_MAX bytes */
	/* The configured values (before any saved file was loaded), as the
	 * blob's parts: what 1011h "load" makes the defaults again. */
	uint8_t *factory;
	uint32_t factory_len;
	bool damaged;       /* the saved set could not be loaded: EMCY */
} line_store_req;

#define LINE_STORE_MAX (256u * 1024u)

/* Access settings handed over by a reload (main thread -> line thread).
 * The main thread fills the fields only while state is 0, then sets 1;
 * the line thread applies them and sets 0 again. No lock on the RT path. */
typedef struct line_access_req {
	atomic_int state;
	mbx_access_rule rules[MBX_SERVER_RULES_MAX];
	size_t n_rules;
	uint8_t default_access;
	unsigned lease_ms;
} line_access_req;

struct line {
	line_params p;
	char name[32];
	char ifname[32];
	char state_path[320];

	co_node *node;
	can_port *port;
	mbx_server *mbx;
	int epfd, timerfd, wakefd;
	uint64_t armed_us;
	bool epollout;
	uint64_t now_us;   /* read once per loop iteration */

	pthread_t thread;
	bool started;
	atomic_bool stop;
	atomic_bool up;
	atomic_uint_fast64_t checkin_us;
	atomic_uint stall_ms;
	atomic_int hb_producer_ms; /* -1 = no request */

	/* counters published to the main thread */
	pthread_mutex_t stats_lock; /* trylock only on the line thread */
	line_stats published;
	bool have_stats;
	uint64_t next_publish_us;
	uint64_t loops, max_loop_us;

	line_node_info nodes[LINE_NODES];
	line_pending pending[LINE_PENDING_MAX];
	uint8_t *sdo_bufs; /* LINE_PENDING_MAX x p.mbx.max_transfer */
	uint64_t next_tag;
	uint32_t raw_subscribers; /* cached: any client wants raw frames */
	can_bus_state bus_state_prev;
	line_store_req store;
	line_access_req access;
	unsigned ext_attached; /* p.ext[0..ext_attached) attached */
};

/* line.c: wake the line thread (any thread may call it) */
void line_wake(line *l);

/* line_events.c */
uint8_t line_mbx_can_state(can_bus_state s);
void line_on_core_event(void *ctx, const co_event *ev);
void line_on_can_error(line *l, const can_rx_item *it);
void line_publish_raw(line *l, const co_frame *f, uint64_t ts_ns);

/* line_cmds.c */
void line_dispatch(void *ctx, mbx_server *srv, const mbx_request *req);
void line_client_gone(void *ctx, mbx_server *srv, uint32_t client);
line_pending *line_pending_find(line *l, uint64_t tag);
void line_lss_done(line *l, const co_ev_lss_master *m);
void line_pending_release(line *l, line_pending *pp);

/* line_store.c */
int line_store_attach(line *l);
int line_store_load(line *l);
/* Line thread, once the node runs: EMCY 6300h (data set) if the saved
 * parameters were damaged and the configured values are in use. */
void line_store_started(line *l);
void line_store_poll(line *l); /* on wake-up: finish a completed save */
/* Start a save (op 1) or restore (op 2) for a mailbox request. Returns 0,
 * -EBUSY (one already running) or -EINVAL. */
int line_store_request_mbx(line *l, uint8_t op, uint8_t sub, const mbx_reply_to *to);

#endif /* COGW_LINES_LINE_INTERNAL_H */
