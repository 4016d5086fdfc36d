/* SPDX-License-Identifier: MIT */
/*
 * apps/common/config_reload.c - what a reload may change: the difference
 * between the running configuration and a new one, named key by key with
 * its JSON path where it needs a restart (cogw_config_reload_check), and
 * node by node where the line follows at run time (cogw_config_node_diff;
 * config.h, docs/config.md "Reload").
 */
#include <stdio.h>
#include <string.h>

#include "apps/common/config.h"
#include "apps/common/pdo_config.h"
#include "core/cfgmgr.h"

/* The keys that differ, "a: needs a restart; b: needs a restart", and
 * whether any does. */
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
	snprintf(d->what + used, d->len - used, "%s%s: needs a restart", used ? "; " : "", name);
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
 * and the manager's objects of each node (1F81h, 1F84h..1F88h, 1F22h,
 * 1F26h, 1F27h, 1F55h), which "nodes" explains (cogw_config_node_diff). */
static bool od_skip(uint16_t index)
{
	return index == 0x1016 || index == 0x1017 || index == 0x1F81 ||
	       (index >= 0x1F84 && index <= 0x1F88) || index == 0x1F55 ||
	       index == CO_CFGMGR_IDX_CDCF || index == CO_CFGMGR_IDX_DATE ||
	       index == CO_CFGMGR_IDX_TIME;
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

/* "app": the bounds and the declared objects, in order. */
static bool app_same(const cogw_app_config *x, const cogw_app_config *y)
{
	return x->max_created == y->max_created && x->max_per_client == y->max_per_client &&
	       x->indications == y->indications && x->n_decl == y->n_decl &&
	       !memcmp(x->decl, y->decl, x->n_decl * sizeof x->decl[0]);
}

/* Everything a node entry says that the line follows at run time. */
static bool node_same(const cogw_node *a, const cogw_node *b)
{
	return a->id == b->id && cogw_node_config_equal(&a->config, &b->config) &&
	       a->assignment == b->assignment &&
	       !memcmp(a->identity, b->identity, sizeof(a->identity)) &&
	       a->heartbeat_ms == b->heartbeat_ms && a->keep_op == b->keep_op &&
	       a->target_state == b->target_state && cogw_node_pdo_equal(a, b);
}

/* The program download of a node is not changed at run time: the image
 * is read at start-up and the software manager holds it. */
static bool node_software_same(const cogw_node *a, const cogw_node *b)
{
	uint32_t sw_a = a ? a->software_id : 0, sw_b = b ? b->software_id : 0;
	size_t len_a = a ? a->program_len : 0, len_b = b ? b->program_len : 0;

	return sw_a == sw_b && len_a == len_b && (!len_a || !memcmp(a->program, b->program, len_a));
}

/* The heartbeat consumers of "heartbeat_consumers" alone: 1016h also
 * holds the entries of the nodes' heartbeat_ms (config_line.c reads them
 * all back). */
static bool consumer_is_node(const cogw_line_config *l, const cogw_hb_consumer *h)
{
	for (size_t i = 0; i < l->n_nodes; i++)
		if (l->nodes[i].id == h->node_id && l->nodes[i].heartbeat_ms == h->time_ms)
			return true;
	return false;
}

size_t cogw_config_consumers(const cogw_line_config *l, uint16_t out[128])
{
	size_t n = 0;

	memset(out, 0, 128 * sizeof out[0]);
	for (size_t i = 0; i < l->n_hb_consumers; i++)
		if (!consumer_is_node(l, &l->hb_consumers[i]) && l->hb_consumers[i].node_id < 128) {
			out[l->hb_consumers[i].node_id] = l->hb_consumers[i].time_ms;
			n++;
		}
	return n;
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
	LDIFF(!app_same(&x->app, &y->app) || memcmp(&x->appwd, &y->appwd, sizeof(x->appwd)), "app");
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

void cogw_nodes_by_id(const cogw_line_config *l, const cogw_node *out[128])
{
	memset(out, 0, 128 * sizeof out[0]);
	for (size_t i = 0; i < l->n_nodes; i++)
		if (l->nodes[i].id < 128)
			out[l->nodes[i].id] = &l->nodes[i];
}

static void add_change(cogw_node_diff *out, uint8_t kind, const cogw_node *n, size_t index)
{
	out->change[out->n++] =
		(cogw_node_change){ .kind = kind, .id = n->id, .index = index, .node = n };
}

/* A node's program download differs: "lines[i].nodes[j].software_id". */
static void note_software(struct diff *d, const cogw_node *a, const cogw_node *b, size_t line_no,
			  size_t j)
{
	char name[96];

	snprintf(name, sizeof name, "lines[%zu].nodes[%zu].%s", line_no, j,
		 (a ? a->software_id : 0) != b->software_id ? "software_id" : "program");
	note(d, name);
}

/* A concise DCF that does not fit the 1F22h:n made at start-up. */
static void note_room(struct diff *d, const cogw_line_config *started, const cogw_node *b,
		      size_t line_no, size_t j)
{
	uint32_t room = cogw_node_cdcf_room(started, b->id);
	char name[160];

	if (b->config.cdcf_len <= room)
		return;
	snprintf(name, sizeof name,
		 "lines[%zu].nodes[%zu].config (a concise DCF of %zu bytes; 1F22h:%u holds %u)",
		 line_no, j, b->config.cdcf_len, b->id, (unsigned)room);
	note(d, name);
}

bool cogw_config_node_diff(const cogw_node *const cur[128], const cogw_line_config *started,
			   const cogw_line_config *next, size_t line_no, cogw_node_diff *out)
{
	struct diff d = { out->what, sizeof out->what, false };
	const cogw_node *nxt[128];
	char name[64];

	out->n = 0;
	out->what[0] = '\0';
	cogw_nodes_by_id(next, nxt);
	/* removals first: the 1016h entries they free may serve an addition */
	for (unsigned id = 1; id < 128; id++)
		if (cur[id] && !nxt[id])
			add_change(out, COGW_NODE_REMOVED, cur[id], 0);
	for (size_t j = 0; j < next->n_nodes; j++) {
		const cogw_node *b = &next->nodes[j], *a = cur[b->id];

		if (!node_software_same(a, b))
			note_software(&d, a, b, line_no, j);
		if (a && node_same(a, b))
			continue;
		note_room(&d, started, b, line_no, j);
		add_change(out, a ? COGW_NODE_CHANGED : COGW_NODE_ADDED, b, j);
	}
	if (out->n && !next->manager.enabled) {
		/* without a manager nothing on the line follows a node list */
		snprintf(name, sizeof name, "lines[%zu].nodes", line_no);
		note(&d, name);
	}
	return !d.changed;
}
