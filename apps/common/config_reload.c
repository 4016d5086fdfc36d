/* SPDX-License-Identifier: MIT */
/*
 * apps/common/config_reload.c - what a reload may not change: the
 * difference between the running configuration and a new one, named key
 * by key (cogw_config_reload_check in config.h, docs/config.md).
 */
#include <stdio.h>
#include <string.h>

#include "apps/common/config.h"
#include "apps/common/pdo_config.h"
#include "core/cfgmgr.h"

/* The names of what differs, "a, b, c", and whether anything does. */
struct diff {
	char *what;
	size_t len;
	bool changed;
};

static void note(struct diff *d, const char *name)
{
	size_t used;

	d->changed = true;
	if (!d->what || !d->len)
		return;
	used = strlen(d->what);
	snprintf(d->what + used, d->len - used, "%s%s", used ? ", " : "", name);
}

static bool entry_same(const co_od_entry *a, const co_od_entry *b)
{
	if (a->index != b->index || a->sub != b->sub || a->type != b->type ||
	    a->access != b->access || a->max_size != b->max_size || a->obj_code != b->obj_code ||
	    a->has_limits != b->has_limits)
		return false;
	if (co_type_is_variable((co_type)a->type))
		return a->def_size == b->def_size &&
		       (!a->def_size || !memcmp(a->def_data, b->def_data, a->def_size));
	if (a->has_limits && (memcmp(a->min, b->min, a->size) || memcmp(a->max, b->max, a->size)))
		return false;
	return !memcmp(a->def, b->def, a->size);
}

/* Left out of the OD comparison: 1016h/1017h, which a reload may change,
 * and the node configuration objects, which "nodes" explains. */
static bool od_skip(uint16_t index)
{
	return index == 0x1016 || index == 0x1017 || index == CO_CFGMGR_IDX_CDCF ||
	       index == CO_CFGMGR_IDX_DATE || index == CO_CFGMGR_IDX_TIME;
}

/* The ODs agree apart from what od_skip() leaves out. */
static bool od_same(const co_od *a, const co_od *b)
{
	size_t i = 0, j = 0;

	for (;;) {
		const co_od_entry *ea = co_od_at(a, i), *eb = co_od_at(b, j);

		while (ea && od_skip(ea->index))
			ea = co_od_at(a, ++i);
		while (eb && od_skip(eb->index))
			eb = co_od_at(b, ++j);
		if (!ea || !eb)
			return !ea && !eb;
		if (!entry_same(ea, eb))
			return false;
		i++;
		j++;
	}
}

/* Same node ids and configurations, in the same order. */
static bool nodes_same(const cogw_line_config *a, const cogw_line_config *b)
{
	if (a->n_nodes != b->n_nodes)
		return false;
	for (size_t i = 0; i < a->n_nodes; i++)
		if (a->nodes[i].id != b->nodes[i].id ||
		    !cogw_node_config_equal(&a->nodes[i].config, &b->nodes[i].config) ||
		    a->nodes[i].assignment != b->nodes[i].assignment ||
		    memcmp(a->nodes[i].identity, b->nodes[i].identity,
			   sizeof(a->nodes[i].identity)) ||
		    a->nodes[i].heartbeat_ms != b->nodes[i].heartbeat_ms ||
		    a->nodes[i].keep_op != b->nodes[i].keep_op ||
		    a->nodes[i].target_state != b->nodes[i].target_state ||
		    !cogw_node_pdo_equal(&a->nodes[i], &b->nodes[i]))
			return false;
	return true;
}

#define DIFF(cond, label)               \
	do {                            \
		if (cond)               \
			note(d, label); \
	} while (0)

static void top_diff(const cogw_config *cur, const cogw_config *next, struct diff *d)
{
	DIFF(strcmp(cur->state_dir, next->state_dir), "state_dir");
	DIFF(cur->mlockall != next->mlockall, "mlockall");
	DIFF(cur->watchdog_check_ms != next->watchdog_check_ms, "watchdog_check_ms");
	DIFF(cur->file_memory != next->file_memory, "file_memory");
	DIFF(cur->debug_stall_signal != next->debug_stall_signal ||
		     cur->debug_stall_ms != next->debug_stall_ms,
	     "debug");
}

static void mailbox_diff(const cogw_mailbox_config *a, const cogw_mailbox_config *b, struct diff *d)
{
	DIFF(strcmp(a->instance, b->instance), "mailbox.instance");
	DIFF(a->depth != b->depth, "mailbox.depth");
	DIFF(a->msg_size != b->msg_size, "mailbox.msg_size");
	DIFF(a->queue_mode != b->queue_mode, "mailbox.queue_mode");
	DIFF(a->max_clients != b->max_clients, "mailbox.max_clients");
	DIFF(a->max_transfer != b->max_transfer, "mailbox.max_transfer");
	DIFF(a->max_clients_per_uid != b->max_clients_per_uid, "mailbox.max_clients_per_uid");
	DIFF(a->max_outstanding != b->max_outstanding, "mailbox.max_outstanding");
	DIFF(a->max_request_timeout_ms != b->max_request_timeout_ms,
	     "mailbox.max_request_timeout_ms");
	DIFF(a->max_read_outstanding != b->max_read_outstanding, "mailbox.max_read_outstanding");
	DIFF(a->write_reserve != b->write_reserve, "mailbox.write_reserve");
	DIFF(a->transfer_slots != b->transfer_slots, "mailbox.transfer_slots");
	DIFF(a->max_transfers_per_client != b->max_transfers_per_client,
	     "mailbox.max_transfers_per_client");
	DIFF(a->transfer_stall_ms != b->transfer_stall_ms, "mailbox.transfer_stall_ms");
	DIFF(a->transfer_lifetime_ms != b->transfer_lifetime_ms, "mailbox.transfer_lifetime_ms");
	DIFF(a->transfer_memory != b->transfer_memory, "mailbox.transfer_memory");
}
#undef DIFF

/* Line i's differences, named "lines[i].key", into d. */
static void line_diff(const cogw_line_config *x, const cogw_line_config *y, size_t i,
		      struct diff *d)
{
	bool before = d->changed;
	char name[64];

	d->changed = false;
#define LDIFF(cond, key)                                                       \
	do {                                                                   \
		if (cond) {                                                    \
			snprintf(name, sizeof(name), "lines[%zu].%s", i, key); \
			note(d, name);                                         \
		}                                                              \
	} while (0)
	LDIFF(strcmp(x->name, y->name), "name");
	LDIFF(strcmp(x->interface, y->interface), "interface");
	LDIFF(x->bitrate != y->bitrate, "bitrate");
	LDIFF(x->node_id != y->node_id, "node_id");
	LDIFF(x->network_id != y->network_id, "network_id");
	LDIFF(x->sdo_servers != y->sdo_servers, "sdo_servers");
	LDIFF(x->sdo_clients != y->sdo_clients, "sdo_clients");
	LDIFF(x->sdo_timeout_ms != y->sdo_timeout_ms, "sdo_timeout_ms");
	LDIFF(x->sdo_block_threshold != y->sdo_block_threshold, "sdo_block_threshold");
	LDIFF(x->sync_period_us != y->sync_period_us, "sync_period_us");
	LDIFF(x->time_period_ms != y->time_period_ms, "time_period_ms");
	LDIFF(x->id_conflict_quiet_ms != y->id_conflict_quiet_ms, "id_conflict_quiet_ms");
	LDIFF(x->fault_quiet_ms != y->fault_quiet_ms, "fault_quiet_ms");
	/* The OD follows from the keys above: name it only when they do not
	 * explain the difference. */
	LDIFF(!d->changed && x->od && y->od && !od_same(x->od, y->od), "objects/values");
	LDIFF(!nodes_same(x, y), "nodes");
	LDIFF(x->pdo != y->pdo, "pdo");
	LDIFF(x->pdo_scan_max != y->pdo_scan_max, "pdo_scan_max");
	LDIFF(memcmp(&x->manager, &y->manager, sizeof(x->manager)), "manager");
	LDIFF(memcmp(&x->device_objects, &y->device_objects, sizeof(x->device_objects)),
	      "device_objects");
	LDIFF(x->unknown.policy != y->unknown.policy ||
		      x->unknown.heartbeat_ms != y->unknown.heartbeat_ms ||
		      x->unknown.sdo_timeout_ms != y->unknown.sdo_timeout_ms ||
		      x->unknown.identify != y->unknown.identify ||
		      strcmp(x->unknown.devices_dir, y->unknown.devices_dir),
	      "unknown_nodes");
#undef LDIFF
	d->changed = d->changed || before;
}

bool cogw_config_reload_check(const cogw_config *cur, const cogw_config *next, char *what,
			      size_t whatlen)
{
	struct diff d = { what, whatlen, false };

	if (what && whatlen)
		what[0] = '\0';
	top_diff(cur, next, &d);
	mailbox_diff(&cur->mailbox, &next->mailbox, &d);
	if (cur->n_lines != next->n_lines) {
		note(&d, "lines (count)");
	} else {
		for (size_t i = 0; i < cur->n_lines; i++)
			line_diff(&cur->lines[i], &next->lines[i], i, &d);
	}
	return !d.changed;
}
