/* SPDX-License-Identifier: MIT */
/*
 * apps/cogwd/ext_devobj.c - the device object extension's provider
 * (devobj/devobj.h): every line gets one; the nodes with pdo "auto" are
 * mirrored, "device_objects" sets its limits and times.
 */
#include "apps/cogwd/extensions.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "devobj/devobj.h"

static void line_params(const cogw_line_config *lc, devobj_line_params *o)
{
	memcpy(o->name, lc->name, sizeof o->name);
	o->read_max_age_ms = lc->device_objects.read_max_age_ms;
	o->write_update_ms = lc->device_objects.write_update_ms;
	o->watches = lc->device_objects.watches;
	memset(o->mirror_nodes, 0, sizeof o->mirror_nodes);
	memset(o->room_nodes, 0, sizeof o->room_nodes);
	/* a manager takes nodes at run time (docs/config.md "Nodes at run
	 * time"): every node-ID but the line's own may be mirrored later */
	for (unsigned id = 1; lc->manager.enabled && id <= 127; id++)
		if (id != lc->node_id)
			o->room_nodes[id / 32u] |= 1u << (id % 32u);
	for (size_t i = 0; i < lc->n_nodes; i++) {
		const cogw_node *n = &lc->nodes[i];
		if (n->pdo == COGW_PDO_AUTO)
			o->mirror_nodes[n->id / 32u] |= 1u << (n->id % 32u);
		/* the configuration lives as long as the daemon (a reload
		 * checks a copy and keeps it) */
		o->objects[n->id] = (devobj_node_objects){ .list = n->types, .n = n->n_types };
	}
}

/* gateway.forward[i]: its `from` end on one line, its `to` end on another. */
_Static_assert(COGW_FORWARDS_MAX <= DEVOBJ_FORWARDS_MAX, "a line may hold every end");

static void forward_ends(const cogw_forward *f, devobj_params *p)
{
	const cogw_dev_ref *end[2] = { &f->from, &f->to };
	for (int k = 0; k < 2; k++) {
		const cogw_dev_ref *me = end[k], *peer = end[1 - k];
		devobj_line_params *lp = &p->line[me->line];
		lp->fwd[lp->n_fwd++] = (devobj_forward){ .source = k == 0,
							 .node = me->node,
							 .sub = me->sub,
							 .index = me->index,
							 .image = f->image,
							 .peer_line = peer->line,
							 .peer_node = peer->node,
							 .peer_sub = peer->sub,
							 .peer_index = peer->index };
	}
}

static int devobj_setup(const cogw_config *cfg, void **state)
{
	devobj_params *p = calloc(1, sizeof *p);
	devobj *x = NULL;
	int rc;

	*state = NULL;
	if (!p)
		return -ENOMEM;
	p->n_lines = (unsigned)cfg->n_lines;
	for (size_t i = 0; i < cfg->n_lines; i++)
		line_params(&cfg->lines[i], &p->line[i]);
	for (size_t i = 0; i < cfg->n_forwards; i++)
		forward_ends(&cfg->forwards[i], p);
	rc = devobj_create(&x, p);
	free(p);
	*state = rc ? NULL : x;
	return rc;
}

static void devobj_for_line(void *state, unsigned line_no, line_ext *out)
{
	devobj_line_ext(state, line_no, out);
}

static void devobj_teardown(void *state)
{
	devobj_destroy(state);
}

const cogwd_ext_provider cogwd_ext_devobj = {
	.name = "devobj",
	.setup = devobj_setup,
	.line_ext = devobj_for_line,
	.teardown = devobj_teardown,
};
