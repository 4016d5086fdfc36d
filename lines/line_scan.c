/* SPDX-License-Identifier: MIT */
/*
 * lines/line_scan.c - NODE_SCAN, NODE_SCAN_CACHE and nodes outside the
 * configuration (docs/mailbox.md "Node scan and unknown nodes",
 * docs/config.md "unknown_nodes"). One engine reads what identifies a
 * node - 1000h, then 1018h:1..4 - through the line's SDO client pool into
 * the line's cache (one entry per node-ID). Two users start it:
 *
 *   1. line_scan_command()     a client asks for node-IDs first..last: the
 *                              scan keeps `parallel` nodes in the pool at
 *                              once, each node's reads one after another,
 *                              with a short timeout per frame; a node that
 *                              does not answer 1000h is absent.
 *   2. line_unknown_on_event() a node outside the configuration sent a
 *                              boot-up, a heartbeat or an EMCY: the first
 *                              time, its identity is read (not while it is
 *                              STOPPED: no SDO there, CiA 301 §7.3.2.2).
 *   3. probe_con()             each read's confirmation: the next read, or
 *                              node_done(), which feeds the scan (the next
 *                              node; the answer after the last) and the
 *                              unknown-node report (its policy, the event,
 *                              the log).
 *
 * Why a window of `parallel` nodes and not 127 requests at once: requests
 * that wait in the pool have no timeout running yet (core/sdo_client.h),
 * and the pool's FIFO is shared with the manager's boot and the clients'
 * transfers. With the window, an absent node costs one timeout in its
 * slot, and the scan's bound is ceil(n / parallel) x 5 x timeout (each
 * node at most 5 reads), ceil(absent / parallel) x timeout in practice.
 */
#include "lines/line_internal.h"

#include <errno.h>
#include <string.h>

#include "core/frame.h"
#include "core/heartbeat.h"
#include "core/nmt.h"
#include "core/sdo_client.h"
#include "lines/log.h"

#define SCAN_TAG 0x5343000000000000ull /* "SC" in the top bytes */
#define PROBE_LAST_STEP 5u             /* 1018h:4 */

static bool id_in(const uint32_t set[4], uint8_t node)
{
	return set[node / 32] & (1u << (node % 32));
}

static uint32_t age_ms(uint64_t now_us, uint64_t then_us)
{
	uint64_t ms = (now_us - then_us) / 1000u;
	return ms >= UINT32_MAX ? UINT32_MAX - 1 : (uint32_t)ms;
}

/* The NMT state last heard; a boot-up ends in PRE-OPERATIONAL (CiA 301). */
static uint8_t heard_state(line *l, uint8_t node)
{
	uint8_t st = co_hb_remote_state(l->node, node);
	return st == CO_NMT_INITIALISING ? CO_NMT_PRE_OPERATIONAL : st;
}

static void probe_con(void *arg, const co_ev_sdo_cli *c);

/* The read of the probe's step: 1000h, then 1018h:1..4. */
static int probe_read(line *l, uint8_t node)
{
	struct line_probe *p = &l->scan.probe[node];
	sdo_client_req r = {
		.upload = true,
		.node_id = node,
		.index = p->step == 1 ? 0x1000 : 0x1018,
		.sub = p->step == 1 ? 0 : (uint8_t)(p->step - 1),
		.mode = SDO_MODE_AUTO,
		.timeout_ms = p->timeout_ms,
		.tag = SCAN_TAG | (uint64_t)p->gen << 8 | node,
		.buf = p->buf,
		.cap = sizeof p->buf,
		.con = probe_con,
		.con_arg = l,
	};
	if (p->for_scan)
		l->scan.figures.requests++;
	return sdo_client_pool_submit(l->node, &r, l->now_us);
}

/* Begin reading `node` (0), or join the read under way (0); -errno when
 * the pool refuses (its cache entry says why). */
static int probe_start(line *l, uint8_t node, uint8_t source, uint16_t timeout_ms)
{
	struct line_probe *p = &l->scan.probe[node];
	mbx_node_ident *id = &l->scan.cache[node];
	int rc;
	if (p->step)
		return 0;
	memset(id, 0, sizeof *id);
	id->node = node;
	id->source = source;
	id->nmt_state = heard_state(l, node);
	p->step = 1;
	p->gen++;
	p->timeout_ms = timeout_ms;
	if ((rc = probe_read(l, node)) < 0) {
		p->step = 0;
		id->abort = sdo_abort_of_errno(rc);
		l->scan.read_us[node] = l->now_us;
	}
	return rc;
}

static void scan_fill(line *l);
static void unknown_report(line *l, uint8_t node);

static void node_done(line *l, uint8_t node)
{
	struct line_probe *p = &l->scan.probe[node];
	p->step = 0;
	l->scan.read_us[node] = l->now_us;
	l->scan.cache[node].nmt_state = heard_state(l, node);
	if (p->for_unknown) {
		p->for_unknown = false;
		unknown_report(l, node);
	}
	if (p->for_scan) {
		p->for_scan = false;
		l->scan.in_flight--;
		scan_fill(l);
	}
}

/* What a read gave, into the cache entry; whether the probe goes on. An
 * abort answered by the device still proves a device (PRESENT); 1018h:4
 * (the serial number) is optional in CiA 301. */
static bool probe_took(mbx_node_ident *id, uint8_t step, const co_ev_sdo_cli *c, const uint8_t *buf)
{
	uint32_t v = c->abort ? 0 : (uint32_t)co_get_le(buf, c->size < 4 ? c->size : 4);
	if (c->abort && !id->abort)
		id->abort = c->abort;
	if (step == 1) {
		if (!c->answered && c->abort)
			return false; /* nobody there */
		id->flags |= MBX_IDENT_PRESENT;
		id->device_type = v;
		return true;
	}
	if (c->abort)
		return false;
	uint32_t *field[] = { &id->vendor_id, &id->product_code, &id->revision, &id->serial };
	*field[step - 2] = v;
	if (step == 4)
		id->flags |= MBX_IDENT_IDENTITY;
	if (step == PROBE_LAST_STEP)
		id->flags |= MBX_IDENT_SERIAL;
	return step < PROBE_LAST_STEP;
}

static void probe_con(void *arg, const co_ev_sdo_cli *c)
{
	line *l = arg;
	uint8_t node = (uint8_t)(c->tag & 0xFF);
	struct line_probe *p;
	if ((c->tag & 0xFFFF000000000000ull) != SCAN_TAG || node < 1 || node >= LINE_NODES)
		return;
	p = &l->scan.probe[node];
	if (!p->step || (uint32_t)(c->tag >> 8) != p->gen)
		return;
	if (probe_took(&l->scan.cache[node], p->step, c, p->buf)) {
		p->step++;
		if (probe_read(l, node) == 0)
			return;
	}
	node_done(l, node);
}

/* ---- 1. NODE_SCAN ------------------------------------------------------------- */

/* Found: answered 1000h, or heard while STOPPED; out may be NULL. */
static size_t collect(const line *l, uint8_t first, uint8_t last, mbx_node_ident *out)
{
	size_t n = 0;
	for (unsigned i = first; i <= last; i++) {
		const mbx_node_ident *id = &l->scan.cache[i];
		if (!l->scan.read_us[i] || !(id->flags & (MBX_IDENT_PRESENT | MBX_IDENT_NOT_ASKED)))
			continue;
		if (out) {
			out[n] = *id;
			out[n].age_ms = age_ms(l->now_us, l->scan.read_us[i]);
		}
		n++;
	}
	return n;
}

static void answer_scan(line *l, const mbx_reply_to *to, const mbx_scan_resp *fig, uint8_t first,
			uint8_t last)
{
	struct {
		mbx_scan_resp head;
		mbx_node_ident ids[LINE_NODES];
	} out;
	size_t n = first ? collect(l, first, last, out.ids) : 0;
	out.head = *fig;
	out.head.found = (uint8_t)n;
	line_answer(l, to, 0, 0, &out, sizeof out.head + n * sizeof out.ids[0]);
}

static void scan_end(line *l)
{
	struct line_scan *s = &l->scan;
	s->running = false;
	s->ended_us = l->now_us;
	s->figures.duration_ms = age_ms(l->now_us, s->started_us);
	answer_scan(l, &s->reply, &s->figures, s->figures.first, s->figures.last);
	cogw_log(COGW_LOG_INFO, "line %s: scan of nodes %u..%u: %u found in %u ms (%u requests)",
		 l->name, s->figures.first, s->figures.last,
		 (unsigned)collect(l, s->figures.first, s->figures.last, NULL),
		 s->figures.duration_ms, s->figures.requests);
}

/* Keep the window full; answer when the last node is done. */
static void scan_fill(line *l)
{
	struct line_scan *s = &l->scan;
	while (s->running && s->in_flight < s->figures.parallel && s->next &&
	       s->next <= s->figures.last) {
		uint8_t node = s->next++;
		if (node == co_node_id(l->node))
			continue; /* our own objects need no bus */
		s->probe[node].for_scan = true;
		if (probe_start(l, node, MBX_IDENT_SCAN, s->figures.timeout_ms) < 0) {
			s->probe[node].for_scan = false;
			continue;
		}
		s->in_flight++;
	}
	if (s->running && !s->in_flight && (!s->next || s->next > s->figures.last))
		scan_end(l);
}

void line_scan_command(line *l, const mbx_request *req)
{
	struct line_scan *s = &l->scan;
	mbx_scan_req r;
	uint8_t channels = l->p.node.sdo_client_count;
	memcpy(&r, req->payload, sizeof r);
	if (!channels)
		return line_answer(l, &req->reply, MBX_E_UNSUPPORTED, 0, NULL, 0);
	if (s->running)
		return line_answer(l, &req->reply, MBX_E_BUSY, 0, NULL, 0);
	memset(&s->figures, 0, sizeof s->figures);
	s->figures.first = r.first;
	s->figures.last = r.last;
	s->figures.parallel = r.parallel && r.parallel < channels ? r.parallel : channels;
	s->figures.timeout_ms = r.timeout_ms                  ? r.timeout_ms
				: l->p.unknown.sdo_timeout_ms ? l->p.unknown.sdo_timeout_ms
							      : LINE_SCAN_TIMEOUT_MS;
	unsigned n = (unsigned)r.last - r.first + 1u;
	s->figures.bound_ms = (n + s->figures.parallel - 1u) / s->figures.parallel *
			      PROBE_LAST_STEP * s->figures.timeout_ms;
	s->figures.age_ms = 0;
	s->running = true;
	s->reply = req->reply;
	s->next = r.first;
	s->in_flight = 0;
	s->started_us = l->now_us;
	scan_fill(l);
}

void line_scan_cache_command(line *l, const mbx_request *req)
{
	const struct line_scan *s = &l->scan;
	mbx_scan_resp fig = s->figures;
	fig.age_ms = s->ended_us ? age_ms(l->now_us, s->ended_us) : UINT32_MAX;
	/* every node the line read, by a scan or as an unknown node */
	answer_scan(l, &req->reply, &fig, 1, LINE_NODES - 1);
}

/* ---- 2. unknown nodes --------------------------------------------------------- */

static uint8_t apply_boot(line *l, uint8_t node, const mbx_node_ident *id)
{
	uint32_t ident[5] = { id->device_type, id->vendor_id, id->product_code, id->revision,
			      id->serial };
	if (!(id->flags & MBX_IDENT_IDENTITY))
		return MBX_UNKNOWN_NO_IDENTITY;
	for (unsigned i = 0; i < l->ext_attached; i++) {
		const line_ext *x = &l->p.ext[i];
		if (!x->ops || !x->ops->adopt_node)
			continue;
		int rc = x->ops->adopt_node(x->ctx, l, node, ident);
		return rc == 0         ? MBX_UNKNOWN_BOOTING
		       : rc == -ENOENT ? MBX_UNKNOWN_NO_MATCH
				       : MBX_UNKNOWN_REFUSED;
	}
	return MBX_UNKNOWN_REFUSED; /* no manager on this line */
}

/* The policy (docs/config.md "unknown_nodes"): what the line does now.
 * A booted node gets its heartbeat consumer as well: the boot's error
 * control step (CiA 302-2) waits for it, and comes after SDO round trips,
 * so the consumer set after the boot began is in time for it. */
static uint8_t apply_policy(line *l, uint8_t node, const mbx_node_ident *id)
{
	const line_unknown_params *u = &l->p.unknown;
	uint8_t action = MBX_UNKNOWN_SUPERVISED;
	if (u->policy == MBX_UNKNOWN_IGNORE)
		return MBX_UNKNOWN_NONE;
	if (u->policy == MBX_UNKNOWN_BOOT &&
	    (action = apply_boot(l, node, id)) != MBX_UNKNOWN_BOOTING)
		return action;
	if (!u->heartbeat_ms)
		return u->policy == MBX_UNKNOWN_BOOT ? action : MBX_UNKNOWN_NONE;
	if (co_hb_consumer_set(l->node, node, u->heartbeat_ms, l->now_us) < 0)
		return MBX_UNKNOWN_REFUSED; /* 1016h full (or absent) */
	return action;
}

static const char *not_read_why(const line *l, const mbx_node_ident *id)
{
	if (id->flags & MBX_IDENT_IDENTITY)
		return "";
	if (!(id->flags & MBX_IDENT_NOT_ASKED))
		return " (identity not read)";
	return l->p.unknown.identify ? " (not read: stopped)" : " (not read: identify off)";
}

static void unknown_report(line *l, uint8_t node)
{
	const line_unknown_params *u = &l->p.unknown;
	mbx_ev_unknown_node ev = { .ident = l->scan.cache[node],
				   .policy = u->policy,
				   .heartbeat_ms = u->heartbeat_ms };
	const mbx_node_ident *id = &ev.ident;
	ev.action = apply_policy(l, node, id);
	ev.reported = ++l->scan.unknown_reported;
	cogw_log(COGW_LOG_WARNING,
		 "line %s: node %u is not configured (%s, state %s): device type %08X, identity "
		 "%08X/%08X/%08X serial %08X%s; policy %s: %s",
		 l->name, node, mbx_ident_source_to_string(id->source),
		 id->nmt_state == CO_HB_STATE_UNKNOWN ? "unknown"
						      : co_nmt_state_to_string(id->nmt_state),
		 (unsigned)id->device_type, (unsigned)id->vendor_id, (unsigned)id->product_code,
		 (unsigned)id->revision, (unsigned)id->serial, not_read_why(l, id),
		 mbx_unknown_policy_to_string(u->policy), mbx_unknown_action_to_string(ev.action));
	mbx_server_publish(l->mbx, MBX_EV_UNKNOWN_NODE, 0, &ev, sizeof ev);
}

static bool unknown_source(const co_event *ev, uint8_t *node, uint8_t *source)
{
	switch (ev->kind) {
	case CO_EV_BOOTUP:
		*node = ev->u.errctrl.node;
		*source = MBX_IDENT_BOOTUP;
		return true;
	case CO_EV_HB_STATE:
		*node = ev->u.errctrl.node;
		*source = MBX_IDENT_HEARTBEAT;
		return true;
	case CO_EV_EMCY_RX:
		*node = ev->u.emcy.node;
		*source = MBX_IDENT_EMCY;
		return true;
	default:
		return false;
	}
}

void line_unknown_on_event(line *l, const co_event *ev)
{
	struct line_scan *s = &l->scan;
	uint8_t node, source;
	if (!unknown_source(ev, &node, &source) || node < 1 || node >= LINE_NODES ||
	    node == co_node_id(l->node) || id_in(l->p.unknown.known, node) ||
	    id_in(s->unknown_seen, node))
		return;
	s->unknown_seen[node / 32] |= 1u << (node % 32);
	/* a boot-up ends in PRE-OPERATIONAL, where SDO is allowed */
	if (!l->p.unknown.identify ||
	    (source != MBX_IDENT_BOOTUP && co_hb_remote_state(l->node, node) == CO_NMT_STOPPED)) {
		mbx_node_ident *id = &s->cache[node];
		memset(id, 0, sizeof *id);
		id->node = node;
		id->source = source;
		id->flags = MBX_IDENT_NOT_ASKED;
		id->nmt_state = heard_state(l, node);
		s->read_us[node] = l->now_us;
		unknown_report(l, node);
		return;
	}
	s->probe[node].for_unknown = true;
	if (probe_start(l, node, source,
			l->p.unknown.sdo_timeout_ms ? l->p.unknown.sdo_timeout_ms
						    : LINE_SCAN_TIMEOUT_MS) < 0) {
		s->probe[node].for_unknown = false;
		unknown_report(l, node);
	}
}
