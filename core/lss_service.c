/* SPDX-License-Identifier: MIT */
/*
 * The one core service (co_svc_lss, core/lss.h) that hosts the LSS master
 * and the LSS slave end in node->lss: init, tick and reset communication
 * of whichever ends the node configuration enables.
 */
#include <errno.h>
#include <stdlib.h>

#include "core/co_internal.h"
#include "core/lss.h"
#include "core/lss_master.h"
#include "core/lss_slave.h"

static void lss_fini(co_node *node)
{
	struct co_lss *l = node->lss;

	if (!l)
		return;
	lss_master_fini(l->master);
	lss_slave_fini(l->slave);
	free(l);
	node->lss = NULL;
}

static int lss_init(co_node *node)
{
	struct co_lss *l;
	int rc;

	if (!node->cfg.lss_master && !node->cfg.lss_slave)
		return 0; /* slot stays NULL: the node does no LSS */
	l = calloc(1, sizeof(*l));
	if (!l)
		return -ENOMEM;
	node->lss = l;
	if (node->cfg.lss_slave && (rc = lss_slave_init(node, &l->slave)) != 0)
		return rc; /* the core runs fini on failure */
	if (node->cfg.lss_master && (rc = lss_master_init(node, &l->master)) != 0)
		return rc;
	return 0;
}

static uint64_t lss_tick(co_node *node, uint64_t now_us)
{
	if (!node->lss || !node->lss->master)
		return CO_NO_DEADLINE;
	return lss_master_tick(node->lss->master, now_us);
}

static void lss_reset_comm(co_node *node, uint64_t now_us)
{
	if (node->lss && node->lss->slave)
		lss_slave_reset_comm(node->lss->slave, now_us);
}

const co_service co_svc_lss = {
	.name = "lss",
	.init = lss_init,
	.fini = lss_fini,
	.tick = lss_tick,
	.reset_comm = lss_reset_comm,
};
