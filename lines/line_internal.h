/* SPDX-License-Identifier: MIT */
/*
 * lines/line_internal.h - the line object, shared by the files of lines/.
 * Everything here belongs to the line thread unless marked atomic.
 *
 * Who does what (calls only go down this list, never back up):
 *   line.c           the thread, its epoll loop and the extensions' ops
 *   line_dispatch.c  mailbox command -> its handler, by a table
 *   line_sdo.c, line_lss.c, line_od.c, line_nmt.c, line_bus.c,
 *   line_store.c,
 *   line_appwd.c       one family of mailbox commands each: the request
 *                    and its completion in the same file
 *   line_app.c,
 *   line_app_ind.c   objects clients own and their indications
 *                    (line_app.h; line_od.c hands owned objects over)
 *   line_events.c    core and CAN events -> mailbox events
 *   line_scan.c      NODE_SCAN, its cache, nodes outside the configuration
 *   line_pdo.c       RPDO supervision: its events and RPDO_STATUS
 *   line_time.c      the TIME producer's clock
 *   line_pending.c   the table of requests waiting for the core
 * The small helpers every file needs are inline below, so that no file
 * has to call back into line.c.
 */
#ifndef COGW_LINES_LINE_INTERNAL_H
#define COGW_LINES_LINE_INTERNAL_H

#include <pthread.h>
#include <stdatomic.h>
#include <time.h>
#include <sys/eventfd.h>

#include "core/event.h"
#include "lines/line.h"
#include "lines/line_app.h"
#include "lines/line_pending.h"

#define LINE_NODES 128
#define LINE_APPWD_HOLDERS 8

/* What only the line counts about a remote node; states, supervision and
 * times come from the heartbeat consumer (core/heartbeat.h). */
typedef struct line_node_info {
	uint32_t bootups;
	uint16_t last_emcy;
	uint32_t emcy_count;
	uint32_t duplicate_answers; /* second answers to one SDO request */
} line_node_info;

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
	uint8_t *blob; /* serialised values, LINE_STORE_MAX bytes */
	/* The configured values (before any saved file was loaded), as the
	 * blob's parts: what 1011h "load" makes the defaults again. */
	uint8_t *factory;
	uint32_t factory_len;
	bool damaged; /* the saved set could not be loaded: EMCY */
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

/* A node change handed over by a reload (main thread -> line thread,
 * lines/line_nodes.c): the main thread fills `set` while state is FREE
 * (or DONE), then sets POSTED; the line thread applies it, writes rc and
 * sets DONE. No lock on the RT path. */
enum {
	LINE_NODE_FREE = 0,
	LINE_NODE_POSTED,
	LINE_NODE_DONE
};
typedef struct line_node_req {
	atomic_int state;
	line_node_set set;
	bool consumer_only; /* only set.req.node's 1016h entry (heartbeat_ms) */
	int rc;
} line_node_req;

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
	uint64_t now_us; /* read once per loop iteration */

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
	line_pending_table pending;
	uint32_t raw_subscribers; /* cached: any client wants raw frames */
	/* SYNC can come every ms: cached like raw_subscribers */
	uint32_t sync_subscribers;
	/* RPDO supervision episodes begun, by fault kind (line_pdo.c) */
	uint32_t rpdo_episodes[CO_PDO_FAULT_KINDS];
	/* the TIME producer (line_time.c) */
	uint64_t time_next_us;  /* next TIME due (p.time_period_ms) */
	uint64_t time_unusable; /* not produced: clock outside 1984..2163 */
	bool time_clock_logged;
	can_bus_state bus_state_prev;
	struct line_health {
		uint8_t tec, rec;  /* last error counters an error frame carried */
		uint32_t restarts; /* controller restarts after bus-off */
		bool pressure_active;
		bool pressure_seen;
		uint32_t pressure_episodes;
		uint64_t pressure_last_us;
		/* port counters already turned into fault occurrences */
		uint64_t seen_rx_drops, seen_tx_lost;
		/* port counters at the last LINE_HEALTH_RESET */
		uint64_t base_rx_drops, base_tx_drops, base_tx_errors;
	} health; /* line_health.c */
	struct line_link {
		bool down;   /* the interface went down or was deleted */
		bool reopen; /* it was deleted: a new socket when it is back */
		uint32_t episodes, reopens;
		uint32_t last_outage_ms;
		uint64_t since_us, next_probe_us;
	} link; /* line_link.c */
	struct line_scan {
		mbx_node_ident cache[LINE_NODES]; /* what was read, by node-ID */
		uint64_t read_us[LINE_NODES];     /* when (0 = never) */
		struct line_probe {
			uint8_t step; /* 0 idle, 1 1000h, 2..5 1018h:1..4 */
			bool for_scan, for_unknown;
			uint8_t buf[4];
			uint16_t timeout_ms;
			uint32_t gen; /* in the tag: stale confirmations */
		} probe[LINE_NODES];
		uint32_t unknown_seen[4]; /* heard and reported (or being read) */
		uint32_t unknown_reported;
		bool running;            /* a NODE_SCAN runs */
		mbx_reply_to reply;      /* ... and waits for its answer */
		uint8_t next, in_flight; /* next node-ID to ask, nodes being read */
		uint64_t started_us, ended_us;
		mbx_scan_resp figures; /* of the running or last scan */
	} scan;                        /* line_scan.c */
	/* the link may have changed: bus state changes, receive errors
	 * (ENETDOWN when the interface goes down); line_link_events */
	uint32_t link_events;
	struct line_appwd {
		co_appwd wd;
		co_appwd_effects fx;                  /* what trips left behind */
		uint32_t holders[LINE_APPWD_HOLDERS]; /* clients holding OPERATIONAL */
		uint8_t n_holders;
		bool start_deferred; /* a start was refused: applied at the release */
		bool host_not_ready;
		bool not_ready_nmt; /* host not ready stopped the network */
		uint64_t not_ready_episodes, starts_refused;
		struct {
			uint32_t client, pid, done, late_us;
			uint64_t at_us;
		} last; /* the last trip */
	} appwd;        /* line_appwd.c */
	line_store_req store;
	line_access_req access;
	line_node_req node_req;
	unsigned ext_attached; /* p.ext[0..ext_attached) attached */
	/* TPDO frames an extension builds from named objects (line_ext.h,
	 * line_tpdo_source.c) */
	struct line_tpdo_sources {
		uint16_t nr; /* 0 = free */
		uint8_t n;
		line_tpdo_source src[LINE_TPDO_SOURCE_ENTRIES];
	} tpdo_sources[LINE_TPDO_SOURCES_MAX];
	uint32_t tpdo_sources_gen;
	line_app *app; /* objects clients own (line_app.c) */
};

/* lines/line_nodes.c: apply a node change the main thread posted. */
void line_nodes_poll(line *l);
/* A control thread's hand-over to the line thread (the access rules, a
 * node change): up to 200 waits of 5 ms for `state` to leave `busy`; the
 * line loops at least every checkin_ms/2, so only a stuck line runs out.
 * Inline: both callers' files are below line.c (no call back up). */
static inline bool line_wait_state_leaves(atomic_int *state, int busy)
{
	for (int i = 0; atomic_load_explicit(state, memory_order_acquire) == busy; i++) {
		if (i >= 200)
			return false;
		struct timespec ts = { .tv_nsec = 5 * 1000000L };
		nanosleep(&ts, NULL);
	}
	return true;
}

/* Wake the line thread (any thread may call it): an eventfd counter never
 * blocks, a pending wake-up just adds up. */
static inline void line_wake(line *l)
{
	eventfd_write(l->wakefd, 1);
}

/* Answer a mailbox request (now, or later with a saved reply address). */
static inline void line_answer(line *l, const mbx_reply_to *to, int status, uint32_t abort,
			       const void *payload, size_t len)
{
	mbx_server_respond(l->mbx, to, status, abort, payload, len);
}

/* The CAN controller state as the mailbox reports it. */
static inline uint8_t line_mbx_can_state(can_bus_state s)
{
	switch (s) {
	case CAN_BUS_ACTIVE:
		return MBX_CAN_ACTIVE;
	case CAN_BUS_WARNING:
		return MBX_CAN_WARNING;
	case CAN_BUS_PASSIVE:
		return MBX_CAN_PASSIVE;
	case CAN_BUS_OFF:
		return MBX_CAN_BUS_OFF;
	}
	return MBX_CAN_ACTIVE;
}

/* Does a mailbox command need the bus (a frame out, an answer back)? What
 * a line whose interface is down refuses (line_link.c), and the start of
 * what host not ready refuses (line_appwd.c). */
static inline bool line_cmd_needs_bus(uint16_t code)
{
	switch (code) {
	case MBX_CMD_SDO_UPLOAD:
	case MBX_CMD_SDO_DOWNLOAD:
	case MBX_CMD_NODE_SCAN:
	case MBX_CMD_GW_SDO_UPLOAD:
	case MBX_CMD_GW_SDO_DOWNLOAD:
	case MBX_CMD_NMT:
	case MBX_CMD_RAW_SEND:
	case MBX_CMD_PDO_REQUEST:
	case MBX_CMD_EMCY_SEND:
	case MBX_CMD_MGR_BOOT:
	case MBX_CMD_MGR_START:
	case MBX_CMD_MGR_REQUEST_NMT:
	case MBX_CMD_MGR_PROGRAM:
	case MBX_CMD_DEV_WRITE:
		return true;
	default:
		return code >= MBX_CMD_LSS_SWITCH_GLOBAL && code <= MBX_CMD_LSS_FASTSCAN;
	}
}

/* A mailbox command handler: payload fields already validated by the
 * mailbox (sizes, ranges, access). */
typedef void (*line_cmd_fn)(line *l, const mbx_request *req);

/* line_dispatch.c: the mailbox server's dispatch ops */
void line_dispatch(void *ctx, mbx_server *srv, const mbx_request *req);
void line_client_gone(void *ctx, mbx_server *srv, uint32_t client);

/* line_sdo.c */
void line_sdo_upload(line *l, const mbx_request *req);
void line_sdo_download(line *l, const mbx_request *req);
/* MBX_CMD_GW_SDO_*: with a node of a network, routed by the extension
 * that routes (line_ext.h sdo_route); UNSUPPORTED without one. */
void line_sdo_upload_net(line *l, const mbx_request *req);
void line_sdo_download_net(line *l, const mbx_request *req);
/* A client left: cancel its transfers (each exactly where it is). */
void line_sdo_client_gone(line *l, uint32_t client);

/* line_lss.c */
void line_lss_command(line *l, const mbx_request *req);
void line_lss_client_gone(line *l, uint32_t client);

/* line_od.c */
void line_od_read(line *l, const mbx_request *req);
void line_od_write(line *l, const mbx_request *req);
void line_pdo_write(line *l, const mbx_request *req);
void line_pdo_request(line *l, const mbx_request *req);
/* An SDO_UPLOAD / SDO_DOWNLOAD (also routed) to the line's own node-ID,
 * answered from its own object dictionary. */
void line_od_sdo_own(line *l, const mbx_request *req, uint16_t index, uint8_t sub, bool upload);

/* line_nmt.c */
void line_nmt_command(line *l, const mbx_request *req);
void line_node_table(line *l, const mbx_request *req);

/* line_bus.c */
void line_status(line *l, const mbx_request *req);
void line_emcy_send(line *l, const mbx_request *req);
void line_raw_send(line *l, const mbx_request *req);

/* line_events.c */
void line_on_core_event(void *ctx, const co_event *ev);
void line_publish_raw(line *l, const co_frame *f, uint64_t ts_ns);

/* line_scan.c */
void line_scan_command(line *l, const mbx_request *req);       /* NODE_SCAN */
void line_scan_cache_command(line *l, const mbx_request *req); /* NODE_SCAN_CACHE */
/* A core event that may come from a node outside the configuration
 * (boot-up, heartbeat state, EMCY): reported once, its policy applied. */
void line_unknown_on_event(line *l, const co_event *ev);

/* line_link.c */
/* The socket said the interface is down (ENETDOWN) or gone (ENODEV). */
void line_link_lost(line *l, int err);
/* While down: look at the interface when due; the next look's time
 * (UINT64_MAX when up). *reopened: the port has a new socket, which the
 * caller watches instead of the old one. */
uint64_t line_link_poll(line *l, bool *reopened);
/* A frame was received: while down, look at the interface at once. */
void line_link_frame_heard(line *l);
/* While down: does this command need the bus (refused with MBX_E_STATE)? */
bool line_link_refuses(const line *l, uint16_t code);

/* line_health.c */
int line_health_attach(line *l); /* after the node exists */
void line_on_can_error(line *l, const can_rx_item *it);
void line_health_on_fault(line *l, const co_ev_commfault *f);
/* After the events of a loop iteration: frames the port lost, the
 * transmit queue's watermarks. */
void line_health_poll(line *l);
void line_health(line *l, const mbx_request *req);
void line_health_reset(line *l, const mbx_request *req);

/* line_pdo.c */
void line_publish_rpdo_fault(line *l, const co_event *ev);
void line_rpdo_status(line *l, const mbx_request *req);

/* line_time.c: produce the TIME that is due; the next one's time
 * (UINT64_MAX: the line produces none). */
uint64_t line_time_poll(line *l);

/* line_appwd.c: the application watchdog, the hold on OPERATIONAL, host
 * ready (MBX_CMD_APP_*, MBX_CMD_HOST_READY) */
void line_appwd_attach(line *l); /* after the node exists */
void line_appwd_command(line *l, const mbx_request *req);
void line_appwd_client_gone(line *l, uint32_t client);
void line_appwd_on_nmt(line *l, const co_ev_nmt *ev);
/* Trip what is due; the next deadline (CO_NO_DEADLINE: none). */
uint64_t line_appwd_poll(line *l);
/* While the host is not ready: does this request reach the line's nodes
 * (or its safe outputs), refused with MBX_E_STATE? */
bool line_appwd_refuses(const line *l, const mbx_request *req);

/* line_store.c */
int line_store_attach(line *l);
int line_store_load(line *l);
/* Line thread, once the node runs: EMCY 6300h (data set) if the saved
 * parameters were damaged and the configured values are in use. */
void line_store_started(line *l);
void line_store_poll(line *l);                            /* on wake-up: finish a completed save */
void line_store_command(line *l, const mbx_request *req); /* STORE, RESTORE */

#endif /* COGW_LINES_LINE_INTERNAL_H */
