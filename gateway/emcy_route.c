/* SPDX-License-Identifier: MIT */
/*
 * gateway/emcy_route.c - the EMCY routing decision (see emcy_route.h).
 */
#include "gateway/emcy_route.h"

#include <string.h>

uint16_t gw_emcy_route_plan(const gw_route_table *t, uint32_t bits, gw_emcy_plan *plan)
{
	memset(plan, 0, sizeof(*plan));
	for (uint16_t net = 1; net <= GW_EMCY_NETS; net++) {
		const gw_route *r;

		if (!gw_emcy_route_has(bits, net))
			continue;
		r = &t->r[net];
		if (r->kind == GW_ROUTE_NONE || r->line >= t->n_lines)
			plan->unknown++;
		else if (r->line == t->own_line)
			plan->loops++;
		else
			plan->lines |= (uint16_t)(1u << r->line);
	}
	return plan->lines;
}
