/* SPDX-License-Identifier: MIT */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "tests/unit/support/test_bus.h"

void tb_init(tb_bus *bus)
{
	memset(bus, 0, sizeof(*bus));
	bus->log_on = true;
	bus->now = 1000000; /* t = 1 s: keeps "0 = unset" bugs visible */
}

void tb_fini(tb_bus *bus)
{
	for (int i = 0; i < bus->n; i++) {
		co_node_destroy(bus->port[i].node);
		co_od_destroy(bus->port[i].od);
	}
	free(bus->q);
	free(bus->q_from);
	free(bus->log);
	free(bus->log_from);
	free(bus->log_t);
	memset(bus, 0, sizeof(*bus));
}

static void enqueue(tb_bus *bus, const co_frame *f, int from)
{
	if (bus->q_len == bus->q_cap) {
		/* Linearise the ring into bigger arrays. */
		size_t cap = bus->q_cap ? bus->q_cap * 2 : 256;
		co_frame *nq = malloc(cap * sizeof(*nq));
		int *nf = malloc(cap * sizeof(*nf));
		if (!nq || !nf)
			abort();
		for (size_t i = 0; i < bus->q_len; i++) {
			nq[i] = bus->q[(bus->q_head + i) % bus->q_cap];
			nf[i] = bus->q_from[(bus->q_head + i) % bus->q_cap];
		}
		free(bus->q);
		free(bus->q_from);
		bus->q = nq;
		bus->q_from = nf;
		bus->q_head = 0;
		bus->q_cap = cap;
	}
	size_t pos = (bus->q_head + bus->q_len) % bus->q_cap;
	bus->q[pos] = *f;
	bus->q_from[pos] = from;
	bus->q_len++;
}

static void log_frame(tb_bus *bus, const co_frame *f, int from)
{
	if (bus->log_len == bus->log_cap) {
		size_t cap = bus->log_cap ? bus->log_cap * 2 : 1024;
		bus->log = realloc(bus->log, cap * sizeof(*bus->log));
		bus->log_from = realloc(bus->log_from, cap * sizeof(*bus->log_from));
		bus->log_t = realloc(bus->log_t, cap * sizeof(*bus->log_t));
		if (!bus->log || !bus->log_from || !bus->log_t)
			abort();
		bus->log_cap = cap;
	}
	bus->log[bus->log_len] = *f;
	bus->log_from[bus->log_len] = from;
	bus->log_t[bus->log_len] = bus->now;
	bus->log_len++;
}

static void put(tb_bus *bus, const co_frame *f, int from)
{
	tb_action a = TB_DELIVER;

	if (bus->log_on)
		log_frame(bus, f, from);
	if (bus->filter)
		a = bus->filter(bus->filter_ctx, f, from, bus->frame_no);
	bus->frame_no++;
	if (a == TB_DROP)
		return;
	enqueue(bus, f, from);
	if (a == TB_DUP)
		enqueue(bus, f, from);
}

static int port_send(void *ctx, const co_frame *f)
{
	tb_port *p = ctx;

	if (p->bus->fail_send)
		return -ENOBUFS;
	put(p->bus, f, p->idx);
	return 0;
}

static void port_event(void *ctx, const co_event *ev)
{
	tb_port *p = ctx;

	if (p->n_ev < TB_MAX_EVENTS)
		p->ev[p->n_ev++] = *ev;
	else {
		memmove(&p->ev[0], &p->ev[1], (TB_MAX_EVENTS - 1) * sizeof(p->ev[0]));
		p->ev[TB_MAX_EVENTS - 1] = *ev;
	}
	if (p->ext_event)
		p->ext_event(p->ext_ctx, ev);
}

tb_port *tb_add_node(tb_bus *bus, co_node_config *cfg, co_od *od)
{
	tb_port *p;

	if (bus->n >= TB_MAX_NODES)
		return NULL;
	p = &bus->port[bus->n];
	memset(p, 0, sizeof(*p));
	p->bus = bus;
	p->idx = bus->n;
	p->od = od;
	p->deliver = true;
	cfg->od = od;
	cfg->send = port_send;
	cfg->send_ctx = p;
	cfg->event = port_event;
	cfg->event_ctx = p;
	if (co_node_create(&p->node, cfg) != 0) {
		co_od_destroy(od);
		return NULL;
	}
	bus->n++;
	return p;
}

size_t tb_pump(tb_bus *bus)
{
	size_t n = 0;

	while (bus->q_len) {
		co_frame f = bus->q[bus->q_head];
		int from = bus->q_from[bus->q_head];
		bus->q_head = (bus->q_head + 1) % bus->q_cap;
		bus->q_len--;
		for (int i = 0; i < bus->n; i++)
			if (i != from && bus->port[i].deliver)
				co_node_recv(bus->port[i].node, &f, bus->now);
		n++;
	}
	return n;
}

void tb_send(tb_bus *bus, const co_frame *f)
{
	put(bus, f, TB_TESTER);
	tb_pump(bus);
}

void tb_send_hex(tb_bus *bus, uint32_t id, const char *hex)
{
	co_frame f = tb_frame(id, hex);
	tb_send(bus, &f);
}

static uint64_t next_deadline(const tb_bus *bus)
{
	uint64_t t = CO_NO_DEADLINE;

	for (int i = 0; i < bus->n; i++) {
		uint64_t d = co_node_next_deadline_us(bus->port[i].node);
		if (d < t)
			t = d;
		if (bus->port[i].ext_deadline) {
			d = bus->port[i].ext_deadline(bus->port[i].ext_ctx);
			if (d < t)
				t = d;
		}
	}
	return t;
}

void tb_advance(tb_bus *bus, uint64_t dt_us)
{
	uint64_t end = bus->now + dt_us;

	tb_pump(bus);
	for (;;) {
		uint64_t t = next_deadline(bus);
		if (t > end)
			break;
		if (t > bus->now)
			bus->now = t;
		for (int i = 0; i < bus->n; i++) {
			tb_port *p = &bus->port[i];
			if (co_node_next_deadline_us(p->node) <= bus->now)
				co_node_tick(p->node, bus->now);
			if (p->ext_tick && p->ext_deadline(p->ext_ctx) <= bus->now)
				p->ext_tick(p->ext_ctx, bus->now);
		}
		tb_pump(bus);
	}
	bus->now = end;
}

void tb_advance_to(tb_bus *bus, uint64_t t_us)
{
	tb_advance(bus, t_us > bus->now ? t_us - bus->now : 0);
}

void tb_settle(tb_bus *bus, uint64_t limit_us)
{
	uint64_t end = bus->now + limit_us;

	tb_pump(bus);
	for (;;) {
		uint64_t t = next_deadline(bus);
		if (t == CO_NO_DEADLINE || t > end)
			break;
		tb_advance(bus, t > bus->now ? t - bus->now : 0);
	}
}

size_t tb_log_count(const tb_bus *bus)
{
	return bus->log_len;
}

const co_frame *tb_log_at(const tb_bus *bus, size_t i)
{
	return i < bus->log_len ? &bus->log[i] : NULL;
}

uint64_t tb_log_time(const tb_bus *bus, size_t i)
{
	return i < bus->log_len ? bus->log_t[i] : 0;
}

size_t tb_log_count_id(const tb_bus *bus, uint32_t id)
{
	size_t n = 0;

	for (size_t i = 0; i < bus->log_len; i++)
		n += bus->log[i].id == id;
	return n;
}

int tb_log_nth_id(const tb_bus *bus, uint32_t id, unsigned n)
{
	for (size_t i = 0; i < bus->log_len; i++)
		if (bus->log[i].id == id && n-- == 0)
			return (int)i;
	return -1;
}

const co_frame *tb_last_from(const tb_bus *bus, int from)
{
	for (size_t i = bus->log_len; i-- > 0;)
		if (bus->log_from[i] == from)
			return &bus->log[i];
	return NULL;
}

size_t tb_count_from(const tb_bus *bus, int from, size_t since)
{
	size_t n = 0;

	for (size_t i = since; i < bus->log_len; i++)
		n += bus->log_from[i] == from;
	return n;
}

const co_frame *tb_last_from_id(const tb_bus *bus, int from, uint32_t id)
{
	for (size_t i = bus->log_len; i-- > 0;)
		if (bus->log_from[i] == from && bus->log[i].id == id)
			return &bus->log[i];
	return NULL;
}

size_t tb_count_from_id(const tb_bus *bus, int from, uint32_t id, size_t since)
{
	size_t n = 0;

	for (size_t i = since; i < bus->log_len; i++)
		n += bus->log_from[i] == from && bus->log[i].id == id;
	return n;
}

void tb_log_clear(tb_bus *bus)
{
	bus->log_len = 0;
}

co_frame tb_frame(uint32_t id, const char *hex)
{
	co_frame f;
	unsigned v;
	int used;
	uint8_t n = 0;

	co_frame_init(&f, id, 0);
	while (n < CO_FRAME_MAX_CLASSIC && sscanf(hex, " %2x%n", &v, &used) == 1) {
		f.data[n++] = (uint8_t)v;
		hex += used;
	}
	f.len = n;
	return f;
}

const char *tb_frame_str(const co_frame *f, char *buf, size_t cap)
{
	size_t o = (size_t)snprintf(buf, cap, "%03X:", (unsigned)f->id);

	for (uint8_t i = 0; i < f->len && o < cap; i++)
		o += (size_t)snprintf(buf + o, cap - o, " %02X", f->data[i]);
	return buf;
}

bool tb_frame_is(const co_frame *f, uint32_t id, const char *hex)
{
	co_frame g = tb_frame(id, hex);

	return f->id == g.id && f->len == g.len && memcmp(f->data, g.data, g.len) == 0;
}

size_t tb_event_count(const tb_port *p, co_event_kind k)
{
	size_t n = 0;

	for (size_t i = 0; i < p->n_ev; i++)
		n += p->ev[i].kind == k;
	return n;
}

const co_event *tb_last_event(const tb_port *p, co_event_kind k)
{
	for (size_t i = p->n_ev; i-- > 0;)
		if (p->ev[i].kind == k)
			return &p->ev[i];
	return NULL;
}

void tb_events_clear(tb_port *p)
{
	p->n_ev = 0;
}

uint32_t tb_od_write(tb_bus *bus, co_node *node, uint16_t index, uint8_t sub, uint64_t v)
{
	co_od_entry *e = co_od_find(co_node_od(node), index, sub);
	co_od_access a = { .origin = CO_OD_ORIGIN_SDO };
	uint8_t b[8];

	if (!e)
		return 0x06020000u;
	for (int i = 0; i < 8; i++)
		b[i] = (uint8_t)(v >> (8 * i));
	co_node_tick(node, bus->now);
	return co_od_write(e, b, e->size > 8 ? 8 : e->size, &a);
}

void evlog_fn(void *ctx, const co_event *ev)
{
	evlog *log = ctx;

	if (log->n < EVLOG_LEN)
		log->ev[log->n++] = *ev;
}

int evlog_find(const evlog *log, unsigned from, co_event_kind kind)
{
	for (unsigned i = from; i < log->n; i++)
		if (log->ev[i].kind == kind)
			return (int)i;
	return -1;
}

unsigned evlog_count(const evlog *log, co_event_kind kind)
{
	unsigned n = 0;

	for (unsigned i = 0; i < log->n; i++)
		n += log->ev[i].kind == kind;
	return n;
}
