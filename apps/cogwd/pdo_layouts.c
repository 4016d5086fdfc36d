/* SPDX-License-Identifier: MIT */
/*
 * apps/cogwd/pdo_layouts.c - see pdo_layouts.h.
 */
#include "apps/cogwd/pdo_layouts.h"

#include <errno.h>

#include "apps/common/pdo_config.h"
#include "lines/log.h"

/* The layout a node's file gives, as the manager would have learnt it. */
static void fill_from_file(co_pdo_layout *t, const char *line_name, const cogw_node *n,
			   uint64_t now_us)
{
	if (co_pdo_layout_begin(t, n->id, CO_PDO_LAYOUT_FILE) < 0)
		return;
	for (unsigned d = 0; d < 2; d++)
		for (unsigned k = 0; k < n->pdo_file.n[d]; k++)
			(void)co_pdo_layout_add(t, n->id, (co_pdo_dir)d, &n->pdo_file.pdo[d][k]);
	co_pdo_layout_commit(t, n->id, now_us);
	cogw_log_pdo_layout(line_name, t, n->id);
	const co_pdo_layout_node *rec = co_pdo_layout_node_get(t, n->id);
	if (rec->dropped[CO_PDO_TX] || rec->dropped[CO_PDO_RX])
		cogw_log(COGW_LOG_WARNING,
			 "line %s: node %u: its file has %u TPDOs and %u RPDOs beyond "
			 "pdo_scan_max %u: not kept",
			 line_name, n->id, rec->dropped[CO_PDO_TX], rec->dropped[CO_PDO_RX],
			 rec->cap);
}

int cogwd_pdo_layouts_create(co_pdo_layout **out, const cogw_line_config *lc, uint64_t now_us)
{
	uint32_t kept[4] = { 0 };
	bool any = false;
	int rc;

	*out = NULL;
	for (size_t i = 0; i < lc->n_nodes; i++)
		if (cogw_node_pdo_kept(&lc->nodes[i])) {
			kept[lc->nodes[i].id / 32u] |= 1u << (lc->nodes[i].id % 32u);
			any = true;
		}
	/* a manager takes nodes at run time (docs/config.md "Nodes at run
	 * time"): room for every node-ID, allocated now (address space until a
	 * layout is learnt), never on the line thread */
	for (unsigned id = 1; lc->manager.enabled && id <= 127; id++)
		if (id != lc->node_id) {
			kept[id / 32u] |= 1u << (id % 32u);
			any = true;
		}
	if (!any)
		return 0;
	if ((rc = co_pdo_layout_create(out, kept, lc->pdo_scan_max)) < 0)
		return rc;
	for (size_t i = 0; i < lc->n_nodes; i++)
		if (lc->nodes[i].pdo_from_file)
			fill_from_file(*out, lc->name, &lc->nodes[i], now_us);
	return 0;
}
