/* SPDX-License-Identifier: MIT */
/*
 * apps/cogwd/ext_gateway.c - the CiA 302-7 gateway's extension provider:
 * turns the configuration into gateway/ parameters (networks, timeouts,
 * the process image B000h..BFFFh of the lines' ODs) and hands each line
 * its gateway extension.
 */
#include "apps/cogwd/extensions.h"

#include "gateway/gateway.h"

_Static_assert(COGW_FORWARDS_MAX <= GW_PINNED_MAX, "a line may be the target of every forward");

static int gw_setup(const cogw_config *cfg, void **state)
{
	gw_params p = { .n_lines = (unsigned)cfg->n_lines, .image_od = cfg->lines[0].od };
	gw *g = NULL;
	int rc;

	for (size_t i = 0; i < cfg->n_lines; i++) {
		p.line[i].network_id = cfg->lines[i].network_id;
		p.line[i].sdo_timeout_ms = cfg->lines[i].sdo_timeout_ms;
	}
	/* a forwarded device object's image object goes to its target line
	 * whether or not a TPDO there maps it (docs/gateway.md) */
	for (size_t i = 0; i < cfg->n_forwards; i++) {
		gw_line_params *lp = &p.line[cfg->forwards[i].to.line];
		lp->pinned[lp->n_pinned++] = cfg->forwards[i].image;
	}
	rc = gw_create(&g, &p);
	*state = rc ? NULL : g;
	return rc;
}

static void gw_for_line(void *state, unsigned line_no, line_ext *out)
{
	gw_line_ext(state, line_no, out);
}

static void gw_teardown(void *state)
{
	gw_destroy(state);
}

const cogwd_ext_provider cogwd_ext_gateway = {
	.name = "gateway",
	.setup = gw_setup,
	.line_ext = gw_for_line,
	.teardown = gw_teardown,
};
