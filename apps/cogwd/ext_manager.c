/* SPDX-License-Identifier: MIT */
/*
 * apps/cogwd/ext_manager.c - the CiA 302-2 manager's extension provider:
 * turns the configuration (the lines' "manager" sections and "nodes")
 * into manager/ parameters and hands each line its manager extension.
 */
#include "apps/cogwd/extensions.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "apps/common/pdo_config.h"
#include "manager/manager_ext.h"

static void line_params(const cogw_line_config *lc, mgr_ext_line_params *o)
{
	const cogw_manager_config *mc = &lc->manager;
	o->enabled = mc->enabled;
	memcpy(o->name, lc->name, sizeof o->name);
	o->mgr = (co_manager_config){ .max_parallel = mc->max_parallel,
				      .sdo_timeout_ms = mc->sdo_timeout_ms,
				      .reset_wait_ms = mc->reset_wait_ms,
				      .retry_ms = mc->retry_ms,
				      .scan_ms = mc->scan_ms,
				      .accept_remote_nmt = mc->accept_remote_nmt };
	o->n_nodes = lc->n_nodes;
	for (size_t i = 0; i < lc->n_nodes; i++) {
		const cogw_node *n = &lc->nodes[i];
		o->nodes[i] = (mgr_ext_node){ .id = n->id,
					      .keep_op = n->keep_op,
					      .target_state = n->target_state,
					      .store = n->config.store,
					      .program = n->program,
					      .program_len = n->program_len,
					      .pdo_scan = cogw_node_pdo_scanned(n),
					      .pdo_from_file = n->pdo_from_file,
					      .pdo_scan_if_reconfigured = n->pdo != COGW_PDO_OFF,
					      .pdo_types = n->types,
					      .n_pdo_types = n->n_types };
	}
}

/* unknown_nodes "boot": the device files of the directory, pointing into
 * the configuration (which outlives the extension). */
static int device_params(const cogw_line_config *lc, mgr_ext_line_params *o, mgr_ext_device **out)
{
	const cogw_unknown_config *u = &lc->unknown;
	mgr_ext_device *d = u->n_devices ? calloc(u->n_devices, sizeof *d) : NULL;
	*out = d;
	if (u->n_devices && !d)
		return -ENOMEM;
	for (size_t i = 0; i < u->n_devices; i++)
		d[i] = (mgr_ext_device){ .file = u->devices[i].file,
					 .ident = { u->devices[i].ident[0], u->devices[i].ident[1],
						    u->devices[i].ident[2],
						    u->devices[i].ident[3] },
					 .cdcf = u->devices[i].cdcf,
					 .cdcf_len = u->devices[i].cdcf_len };
	o->devices = d;
	o->n_devices = u->n_devices;
	return 0;
}

static int mgr_setup(const cogw_config *cfg, void **state)
{
	mgr_ext_params *p = calloc(1, sizeof *p);
	mgr_ext *x = NULL;
	mgr_ext_device *devs[MGR_EXT_LINES_MAX] = { NULL };
	int rc = 0;

	*state = NULL;
	if (!p)
		return -ENOMEM;
	p->n_lines = (unsigned)cfg->n_lines;
	p->msg_size = cfg->mailbox.msg_size;
	for (size_t i = 0; i < cfg->n_lines; i++) {
		line_params(&cfg->lines[i], &p->line[i]);
		if (!rc && i < MGR_EXT_LINES_MAX)
			rc = device_params(&cfg->lines[i], &p->line[i], &devs[i]);
	}
	if (!rc)
		rc = mgr_ext_create(&x, p); /* copies the tables of devices */
	for (size_t i = 0; i < MGR_EXT_LINES_MAX; i++)
		free(devs[i]);
	free(p);
	*state = rc ? NULL : x;
	return rc;
}

static void mgr_for_line(void *state, unsigned line_no, line_ext *out)
{
	mgr_ext_line(state, line_no, out);
}

static void mgr_teardown(void *state)
{
	mgr_ext_destroy(state);
}

const cogwd_ext_provider cogwd_ext_manager = {
	.name = "manager",
	.setup = mgr_setup,
	.line_ext = mgr_for_line,
	.teardown = mgr_teardown,
};
