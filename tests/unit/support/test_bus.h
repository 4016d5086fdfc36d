/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/support/test_bus.h - an in-memory CAN bus for unit tests.
 *
 * Frames sent by a node are queued (not delivered from inside the send
 * callback, exactly like a real bus: a node never sees its own answer
 * arrive while it is still sending). tb_pump() delivers the queue to every
 * other node, in order. The clock is owned by the test: tb_advance() moves
 * it and runs the nodes' timers. Every frame on the bus is logged, with
 * its sender and the bus time it was sent at.
 *
 * The one in-memory bus of the unit tests: the SDO, PDO, SYNC, TIME,
 * store, manager and gateway tests and, through lss_fixture.h, the LSS
 * tests. (errctrl_fixture.h is no bus: one node and the test as its only
 * peer, for NMT, heartbeat, guarding and EMCY.)
 */
#ifndef COGW_TESTS_TEST_BUS_H
#define COGW_TESTS_TEST_BUS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "core/co.h"

#define TB_MAX_NODES 8
#define TB_MAX_EVENTS 256
#define TB_TESTER (-1) /* "from" of frames injected by the test itself */

typedef enum tb_action {
	TB_DELIVER,
	TB_DROP,
	TB_DUP
} tb_action;

/* Called for every frame entering the bus; n counts frames from 0. */
typedef tb_action (*tb_filter_fn)(void *ctx, const co_frame *f, int from, uint64_t n);

typedef struct tb_bus tb_bus;

typedef struct tb_port {
	tb_bus *bus;
	int idx;
	co_node *node;
	co_od *od;
	co_event ev[TB_MAX_EVENTS];
	size_t n_ev;
	bool deliver; /* receives frames from the bus (default true) */
	/* Optional extension driven with the node (a CiA 302 manager): it
	 * sees every event of the node after the port logged it, and is
	 * ticked at its own deadline like the node. */
	void (*ext_event)(void *ctx, const co_event *ev);
	uint64_t (*ext_tick)(void *ctx, uint64_t now_us);
	uint64_t (*ext_deadline)(void *ctx);
	void *ext_ctx;
} tb_port;

struct tb_bus {
	co_frame *q;
	int *q_from;
	size_t q_head, q_len, q_cap;
	co_frame *log;
	int *log_from;
	uint64_t *log_t; /* bus time when sent */
	size_t log_len, log_cap;
	bool log_on;
	bool fail_send; /* every node's send fails with -ENOBUFS (not logged) */
	tb_port port[TB_MAX_NODES];
	int n;
	tb_filter_fn filter;
	void *filter_ctx;
	uint64_t frame_no;
	uint64_t now;
};

void tb_init(tb_bus *bus);
void tb_fini(tb_bus *bus); /* destroys the nodes and their ODs */

/* Create a node on the bus; cfg->send/event/od are filled in. The OD is
 * owned by the bus from here on. Returns the port or NULL. */
tb_port *tb_add_node(tb_bus *bus, co_node_config *cfg, co_od *od);

/* Write an object as an SDO client would (length/limit checks and hooks
 * run), v little-endian, cut to the entry's size; the node is ticked to the
 * bus time first because hooks take the node's current time. Returns 0 or
 * the abort code (0x06020000 if the object does not exist). */
uint32_t tb_od_write(tb_bus *bus, co_node *node, uint16_t index, uint8_t sub, uint64_t v);

/* Deliver queued frames until the bus is quiet; returns frames delivered. */
size_t tb_pump(tb_bus *bus);
/* Inject a frame as the test (tester), then pump. */
void tb_send(tb_bus *bus, const co_frame *f);
void tb_send_hex(tb_bus *bus, uint32_t id, const char *hex);
/* Move the clock by dt_us in steps to each node deadline, ticking and
 * pumping on the way. */
void tb_advance(tb_bus *bus, uint64_t dt_us);
/* The same, to the time t_us (no step back). */
void tb_advance_to(tb_bus *bus, uint64_t t_us);
/* Pump and advance through deadlines until nothing is pending or limit_us
 * of bus time has passed. */
void tb_settle(tb_bus *bus, uint64_t limit_us);

/* Frames logged so far; the i-th; the last one sent by `from`. */
size_t tb_log_count(const tb_bus *bus);
const co_frame *tb_log_at(const tb_bus *bus, size_t i);
const co_frame *tb_last_from(const tb_bus *bus, int from);
void tb_log_clear(tb_bus *bus);
/* Bus time the i-th logged frame was sent at. */
uint64_t tb_log_time(const tb_bus *bus, size_t i);
/* Frames logged with this CAN-ID from any sender; log index of the n-th
 * (0-based) of them, -1 if none. */
size_t tb_log_count_id(const tb_bus *bus, uint32_t id);
int tb_log_nth_id(const tb_bus *bus, uint32_t id, unsigned n);
/* Frames logged from `from` since index `since`. */
size_t tb_count_from(const tb_bus *bus, int from, size_t since);
/* The same, restricted to one CAN-ID (other services, e.g. a heartbeat
 * producer, may share the bus). */
const co_frame *tb_last_from_id(const tb_bus *bus, int from, uint32_t id);
size_t tb_count_from_id(const tb_bus *bus, int from, uint32_t id, size_t since);

/* Parse "23 17 10 00" into a frame (len = number of bytes). */
co_frame tb_frame(uint32_t id, const char *hex);
/* "581: 60 17 10 00 00 00 00 00" into buf. */
const char *tb_frame_str(const co_frame *f, char *buf, size_t cap);
/* True if f has this id and exactly these bytes. */
bool tb_frame_is(const co_frame *f, uint32_t id, const char *hex);

/* Events of a port: count of a kind, last of a kind (NULL if none). */
size_t tb_event_count(const tb_port *p, co_event_kind k);
const co_event *tb_last_event(const tb_port *p, co_event_kind k);
void tb_events_clear(tb_port *p);

/* An event recorder for nodes made outside tb_add_node's event log (a
 * port's ext_event, see lss_fixture.h): stops recording when full. */
#define EVLOG_LEN 512
typedef struct evlog {
	co_event ev[EVLOG_LEN];
	unsigned n;
} evlog;
void evlog_fn(void *ctx, const co_event *ev);
/* Index of the first event of this kind at or after from; -1 if none. */
int evlog_find(const evlog *log, unsigned from, co_event_kind kind);
unsigned evlog_count(const evlog *log, co_event_kind kind);

/* Unity helper: assert that the last frame with this id from `from` has
 * exactly these bytes. */
#define TB_ASSERT_LAST(bus, from, id, hex)                                  \
	do {                                                                \
		const co_frame *f_ = tb_last_from_id((bus), (from), (id));  \
		char b_[96];                                                \
		TEST_ASSERT_NOT_NULL_MESSAGE(f_, "no frame sent");          \
		TEST_ASSERT_TRUE_MESSAGE(tb_frame_is(f_, (id), (hex)),      \
					 tb_frame_str(f_, b_, sizeof(b_))); \
	} while (0)

#endif
