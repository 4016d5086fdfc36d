/* SPDX-License-Identifier: MIT */
/*
 * gateway/route.c - compiling 1F2Ch into a table indexed by network, so
 * that a network indication costs one array access (the kernel's can-gw
 * compiles its jobs the same way: once, when the configuration changes).
 */
#include "gateway/route.h"

#include <string.h>

#include "core/frame.h"
#include "core/sdo.h"

const char *gw_route_kind_to_string(gw_route_kind k)
{
	switch (k) {
	case GW_ROUTE_NONE:
		return "none";
	case GW_ROUTE_DIRECT:
		return "direct";
	case GW_ROUTE_ROUTER:
		return "router";
	}
	return "?";
}

const char *gw_route_outcome_to_string(gw_route_outcome o)
{
	static const char *const names[GW_OUT_COUNT] = {
		[GW_OUT_ROUTED] = "routed",
		[GW_OUT_ABORTED] = "aborted",
		[GW_OUT_TIMED_OUT] = "timed-out",
		[GW_OUT_REFUSED] = "refused",
	};
	return (unsigned)o < GW_OUT_COUNT ? names[o] : "?";
}

void gw_route_table_init(gw_route_table *t, uint8_t own_line, uint8_t n_lines)
{
	memset(t, 0, sizeof(*t));
	t->own_line = own_line;
	t->n_lines = n_lines;
}

uint32_t gw_route_entry_check(uint32_t v, uint8_t n_lines)
{
	gw_route_entry e;

	return gw_route_entry_decode(v, n_lines, &e);
}

uint32_t gw_route_write_check(const co_od_access *a, uint8_t n_lines)
{
	if (!a->data || a->size != 4)
		return SDO_AB_TYPE_LEN;
	return gw_route_entry_check(co_get_le32(a->data), n_lines);
}

void gw_route_table_compile(gw_route_table *t, const uint32_t raw[GW_NET_MAX + 1])
{
	t->compiles++;
	t->bad_entries = 0;
	for (unsigned n = GW_NET_MIN; n <= GW_NET_MAX; n++) {
		gw_route *r = &t->r[n];
		gw_route_entry e;
		uint8_t kind = GW_ROUTE_NONE;

		if (gw_route_entry_decode(raw[n], t->n_lines, &e) != 0)
			t->bad_entries++;
		else if (e.reachable)
			kind = e.router ? GW_ROUTE_ROUTER : GW_ROUTE_DIRECT;
		if (kind == GW_ROUTE_NONE)
			e.line = e.router = 0;
		if (r->kind != kind || r->line != e.line || r->router != e.router)
			memset(r->count, 0, sizeof(r->count));
		r->kind = kind;
		r->line = e.line;
		r->router = e.router;
		r->raw = raw[n];
	}
}

void gw_route_table_compile_od(gw_route_table *t, const co_od *od)
{
	uint32_t raw[GW_NET_MAX + 1] = { 0 };

	for (unsigned n = GW_NET_MIN; n <= GW_NET_MAX; n++)
		if (co_od_get_u32(od, GW_OBJ_ROUTES, (uint8_t)n, &raw[n]) != 0)
			raw[n] = 0;
	gw_route_table_compile(t, raw);
}

void gw_route_count(gw_route_table *t, uint16_t net, gw_route_outcome o)
{
	if (net >= GW_NET_MIN && net <= GW_NET_MAX && (unsigned)o < GW_OUT_COUNT)
		t->r[net].count[o]++;
}

uint32_t gw_route_resolve(gw_route_table *t, uint16_t net, uint8_t node, int from_line, gw_hop *out)
{
	const gw_route *r;

	memset(out, 0, sizeof(*out));
	if (net < GW_NET_MIN || net > GW_NET_MAX)
		return GW_AB_NET_UNKNOWN;
	r = &t->r[net];
	if (r->kind == GW_ROUTE_NONE || (from_line >= 0 && r->line == (unsigned)from_line)) {
		gw_route_count(t, net, GW_OUT_REFUSED);
		return GW_AB_NET_UNKNOWN;
	}
	out->line = r->line;
	out->via_router = r->kind == GW_ROUTE_ROUTER;
	out->node = out->via_router ? r->router : node;
	return 0;
}
