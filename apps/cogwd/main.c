/* SPDX-License-Identifier: MIT */
/*
 * cogwd - the cogw daemon: one real-time thread per CAN line, a mailbox of
 * POSIX message queues per line, systemd notify + watchdog.
 *
 * The main thread owns start-up, signals (signalfd), systemd notification,
 * the watchdog decision, the status line and the file I/O of 1010h "save"
 * (requested by the lines through an eventfd). It never touches a line's
 * core instance.
 */
#include <errno.h>
#include <getopt.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/eventfd.h>
#include <sys/mman.h>
#include <sys/signalfd.h>
#include <sys/stat.h>
#include <systemd/sd-daemon.h>
#include <unistd.h>

#include "apps/cogwd/extensions.h"
#include "apps/cogwd/pdo_layouts.h"
#include "apps/common/config.h"
#include "apps/common/version.h"
#include "lines/line.h"
#include "lines/log.h"
#include "mailbox/proto.h"

#define STARTUP_TIMEOUT_US 5000000u

typedef struct daemon_state {
	const char *config_path; /* NULL = embedded default */
	const char *state_dir_override;
	cogw_config cfg;
	line *lines[COGW_LINES_MAX];
	co_pdo_layout *pdo_layouts[COGW_LINES_MAX]; /* each outlives its line */
	char queue_names[COGW_LINES_MAX][MBX_QNAME_MAX];
	mbx_access_rule rules[COGW_ACCESS_RULES_MAX];
	size_t n_lines;
	int sigfd, wakefd;
	uint64_t watchdog_usec; /* 0 = no systemd watchdog */
	bool watchdog_withheld;
	cogwd_exts exts;            /* manager, gateway: plugged into the lines */
	mbx_budget transfer_memory; /* shared by every line (lock-free) */
	/* Nodes at run time (docs/config.md "Nodes at run time"): what each
	 * line has of "nodes" by node-ID, from the files applied so far, and
	 * the configurations of reloads whose nodes the lines refer to (their
	 * types lists, and concise DCFs a late line may still copy): kept
	 * until the daemon stops. */
	const cogw_node *nodes_in_force[COGW_LINES_MAX][128];
	uint16_t consumers_in_force[COGW_LINES_MAX][128]; /* heartbeat_consumers, ms */
	cogw_config **kept;
	size_t n_kept;
} daemon_state;

static void usage(FILE *to)
{
	fprintf(to, "usage: cogwd [OPTIONS]\n"
		    "  -c, --config FILE     configuration (default: the embedded default,\n"
		    "                        which is etc/cogw.json at build time)\n"
		    "  -s, --state-dir DIR   where 1010h \"save\" persists (overrides the config)\n"
		    "  -t, --check           validate the configuration and exit\n"
		    "      --print-default   print the embedded default configuration\n"
		    "  -v, --verbose         debug log lines\n"
		    "  -h, --help            this text\n"
		    "Signals: SIGTERM/SIGINT stop cleanly, SIGHUP reloads what can change at run "
		    "time.\n");
}

static int load_config(daemon_state *d, cogw_config *cfg)
{
	char err[512];
	int rc = d->config_path
			 ? cogw_config_load_file(cfg, d->config_path, err, sizeof err)
			 : cogw_config_load_string(cfg, cogw_default_config_json,
						   COGW_DEFAULT_CONFIG_SOURCE, err, sizeof err);
	if (rc < 0) {
		cogw_log(COGW_LOG_ERR, "%s", err);
		return rc;
	}
	if (d->state_dir_override)
		snprintf(cfg->state_dir, sizeof cfg->state_dir, "%s", d->state_dir_override);
	return 0;
}

static int prepare_state_dir(const char *dir)
{
	if (!*dir)
		return 0;
	if (mkdir(dir, 0750) != 0 && errno != EEXIST) {
		cogw_log(COGW_LOG_ERR, "state directory %s: %s", dir, strerror(errno));
		return -errno;
	}
	if (access(dir, W_OK) != 0) {
		cogw_log(COGW_LOG_ERR, "state directory %s is not writable: %s", dir,
			 strerror(errno));
		return -errno;
	}
	return 0;
}

static void fill_rules(daemon_state *d)
{
	for (size_t i = 0; i < d->cfg.mailbox.n_rules; i++) {
		d->rules[i].uid = (uint32_t)d->cfg.mailbox.rules[i].uid;
		d->rules[i].access = d->cfg.mailbox.rules[i].access;
	}
}

/* Line i's mailbox: its queue, the configured limits and access rules,
 * and the transfer memory all lines share. */
static mbx_server_config mailbox_params(daemon_state *d, size_t i)
{
	const cogw_mailbox_config *m = &d->cfg.mailbox;

	return (mbx_server_config){
		.queue_name = d->queue_names[i],
		.queue_mode = m->queue_mode,
		.depth = m->depth,
		.msg_size = m->msg_size,
		.max_clients = m->max_clients,
		.lease_ms = m->lease_ms,
		.max_transfer = m->max_transfer,
		.max_clients_per_uid = m->max_clients_per_uid,
		.max_outstanding = m->max_outstanding,
		.max_request_timeout_ms = m->max_request_timeout_ms,
		.read_outstanding = m->max_read_outstanding,
		.write_reserve = m->write_reserve,
		.xfer_slots = m->transfer_slots,
		.xfer_per_client = m->max_transfers_per_client,
		.xfer_timeout_ms = m->transfer_stall_ms,
		.xfer_max_ms = m->transfer_lifetime_ms,
		.budget = &d->transfer_memory,
		.rules = d->rules,
		.n_rules = m->n_rules,
		.default_access = m->default_access,
		/* a stale queue of a crashed daemon must not block a restart */
		.unlink_existing = true,
	};
}

/* What a line does with a node outside its configuration (docs/config.md
 * "unknown_nodes"): the configured nodes are those of "nodes" and of
 * "heartbeat_consumers". */
static line_unknown_params unknown_params(const cogw_line_config *lc)
{
	line_unknown_params u = { .policy = lc->unknown.policy,
				  .heartbeat_ms = lc->unknown.heartbeat_ms,
				  .sdo_timeout_ms = lc->unknown.sdo_timeout_ms,
				  .identify = lc->unknown.identify };
	for (size_t i = 0; i < lc->n_nodes; i++)
		u.known[lc->nodes[i].id / 32] |= 1u << (lc->nodes[i].id % 32);
	for (size_t i = 0; i < lc->n_hb_consumers; i++) {
		uint8_t id = lc->hb_consumers[i].node_id;
		if (id >= 1 && id <= 127)
			u.known[id / 32] |= 1u << (id % 32);
	}
	return u;
}

static int create_lines(daemon_state *d)
{
	const cogw_config *c = &d->cfg;
	fill_rules(d);
	mbx_budget_init(&d->transfer_memory, c->mailbox.transfer_memory);
	for (size_t i = 0; i < c->n_lines; i++) {
		const cogw_line_config *lc = &c->lines[i];
		int rc = mbx_queue_name(d->queue_names[i], sizeof d->queue_names[i],
					c->mailbox.instance, (unsigned)i);
		if (rc < 0) {
			cogw_log(COGW_LOG_ERR,
				 "line %s: cannot form a queue name for instance '%s'", lc->name,
				 c->mailbox.instance);
			return rc;
		}
		if ((rc = cogwd_pdo_layouts_create(&d->pdo_layouts[i], lc, line_now_us())) < 0) {
			cogw_log(COGW_LOG_ERR, "line %s: PDO layout table: %s", lc->name,
				 strerror(-rc));
			return rc;
		}
		line_params p = {
			.index = (uint8_t)i,
			.name = lc->name,
			.network_id = lc->network_id,
			.time_period_ms = lc->time_period_ms,
			.id_conflict_quiet_ms = lc->id_conflict_quiet_ms,
			.fault_quiet_ms = lc->fault_quiet_ms,
			.n_safe_outputs = lc->appwd.n_safe_outputs,
			.app_reactions = lc->appwd.reactions,
			.not_ready_cs = lc->appwd.not_ready_cs,
			.unknown = unknown_params(lc),
			.can = { .ifname = lc->interface, .bitrate = lc->bitrate },
			.node = {
				.node_id = lc->node_id,
				.od = lc->od,
				.sdo_server_count = lc->sdo_servers,
				.sdo_server_timeout_ms = lc->sdo_timeout_ms,
				.sdo_client_count = lc->sdo_clients,
				/* lines[].sdo_timeout_ms is the per-frame timeout of
				 * both ends: mailbox SDO transfers that give none use
				 * the client's own setting */
				.sdo_client_timeout_ms = lc->sdo_timeout_ms,
				.sdo_client_block_threshold = lc->sdo_block_threshold,
				/* The manager is the LSS master of every line: without
				 * this the mailbox's LSS commands all answered
				 * UNSUPPORTED (core timeouts stay at their defaults). */
				.lss_master = true,
			},
			.rt_priority = lc->rt.priority,
			.rt_cpu = lc->rt.cpu,
			.checkin_ms = c->watchdog_check_ms,
			.state_dir = c->state_dir,
			.main_wakefd = d->wakefd,
			.pdo_layout = d->pdo_layouts[i],
			.mbx = mailbox_params(d, i),
		};
		_Static_assert(COGW_SAFE_OUTPUTS_MAX <= LINE_SAFE_OUTPUTS_MAX, "safe outputs");
		memcpy(p.safe_outputs, lc->appwd.safe_outputs,
		       lc->appwd.n_safe_outputs * sizeof p.safe_outputs[0]);
		line_app_decl decl[COGW_APP_DECL_MAX];
		for (uint16_t k = 0; k < lc->app.n_decl; k++)
			decl[k] = (line_app_decl){ .index = lc->app.decl[k].index,
						   .sub = lc->app.decl[k].sub,
						   .kind = lc->app.decl[k].kind,
						   .uid = lc->app.decl[k].uid };
		p.app = (line_app_params){ .decl = decl,
					   .n_decl = lc->app.n_decl,
					   .max_created = lc->app.max_created,
					   .max_per_client = lc->app.max_per_client,
					   .max_ind_per_client = lc->app.indications };
		cogwd_exts_for_line(&d->exts, (unsigned)i, p.ext);
		rc = line_create(&d->lines[i], &p);
		if (rc < 0)
			return rc;
		d->n_lines = i + 1;
	}
	return 0;
}

static void status_line(daemon_state *d, char *buf, size_t len)
{
	size_t off = (size_t)snprintf(buf, len, "%zu line%s:", d->n_lines,
				      d->n_lines == 1 ? "" : "s");
	for (size_t i = 0; i < d->n_lines && off < len; i++) {
		line_stats s;
		if (!line_stats_snapshot(d->lines[i], &s)) {
			off += (size_t)snprintf(buf + off, len - off, " %s starting;",
						line_name(d->lines[i]));
			continue;
		}
		off += (size_t)snprintf(
			buf + off, len - off, " %s %s %u node%s %u.%u%% load %u client%s;",
			line_name(d->lines[i]), can_bus_state_to_string(s.bus_state), s.nodes_seen,
			s.nodes_seen == 1 ? "" : "s", s.bus_load_permille / 10,
			s.bus_load_permille % 10, s.mbx_clients, s.mbx_clients == 1 ? "" : "s");
	}
	if (off > 0 && off < len && buf[off - 1] == ';')
		buf[off - 1] = '\0';
}

/* kB of a "Name:   N kB" line of /proc/self/status, 0 if absent. */
static unsigned long proc_status_kb(const char *name)
{
	char text[256];
	unsigned long kb = 0;
	size_t n = strlen(name);
	FILE *f = fopen("/proc/self/status", "re");

	if (!f)
		return 0;
	while (fgets(text, sizeof text, f))
		if (!strncmp(text, name, n) && text[n] == ':' &&
		    sscanf(text + n + 1, "%lu", &kb) == 1)
			break;
	fclose(f);
	return kb;
}

/* Start-up report: what the configuration reserved for buffers, what big
 * transfers may pin at most, and what is pinned in RAM now (a large
 * max_transfer once silently pinned gigabytes; docs/config.md). */
static void log_memory(const daemon_state *d)
{
	size_t buffers = 0;

	for (size_t i = 0; i < d->n_lines; i++)
		buffers += line_buffer_bytes(d->lines[i]);
	/* Under mlockall(MCL_ONFAULT) what is pinned is what is resident
	 * (VmRSS; VmLck counts locked mappings in full, touched or not);
	 * transfer buffers are address space until a transfer, paid from the
	 * budget, touches them, and give their pages back when it ends. */
	cogw_log(COGW_LOG_NOTICE,
		 "memory: %zu KiB of line buffers reserved as address space (max_transfer %u "
		 "bytes), transfers use at most %u KiB at once (mailbox.transfer_memory), %lu KiB "
		 "%s now",
		 buffers / 1024, d->cfg.mailbox.max_transfer, d->cfg.mailbox.transfer_memory / 1024,
		 proc_status_kb("VmRSS"),
		 d->cfg.mlockall ? "pinned in RAM (mlockall)" : "resident");
}

/* WATCHDOG=1 only while every line thread has looped within the period:
 * a stuck line must let systemd restart us. */
static void watchdog_tick(daemon_state *d, uint64_t now)
{
	if (!d->watchdog_usec)
		return;
	for (size_t i = 0; i < d->n_lines; i++) {
		uint64_t seen = line_last_checkin_us(d->lines[i]);
		if (now > seen && now - seen > d->watchdog_usec / 2) {
			if (!d->watchdog_withheld)
				cogw_log(COGW_LOG_ERR,
					 "line %s has not looped for %llu ms; withholding the "
					 "watchdog ping",
					 line_name(d->lines[i]),
					 (unsigned long long)((now - seen) / 1000u));
			d->watchdog_withheld = true;
			return;
		}
	}
	if (d->watchdog_withheld)
		cogw_log(COGW_LOG_NOTICE, "all lines loop again; watchdog pings resume");
	d->watchdog_withheld = false;
	sd_notify(0, "WATCHDOG=1");
}

static bool rules_differ(const cogw_mailbox_config *a, const cogw_mailbox_config *b)
{
	if (a->n_rules != b->n_rules || a->default_access != b->default_access)
		return true;
	for (size_t i = 0; i < a->n_rules; i++)
		if (a->rules[i].uid != b->rules[i].uid || a->rules[i].access != b->rules[i].access)
			return true;
	return false;
}

/* mailbox.rules, default_access and lease_ms are documented as reloadable:
 * hand them to every line (each line's mailbox server is owned by its
 * thread), where they also apply to clients already registered. */
static void apply_access_reload(daemon_state *d, const cogw_config *next)
{
	const cogw_mailbox_config *cur = &d->cfg.mailbox, *nm = &next->mailbox;
	if (!rules_differ(cur, nm) && cur->lease_ms == nm->lease_ms)
		return;
	mbx_access_rule rules[COGW_ACCESS_RULES_MAX];
	for (size_t i = 0; i < nm->n_rules; i++) {
		rules[i].uid = (uint32_t)nm->rules[i].uid;
		rules[i].access = nm->rules[i].access;
	}
	bool all = true;
	for (size_t i = 0; i < d->n_lines; i++) {
		int rc = line_request_access(d->lines[i], rules, nm->n_rules, nm->default_access,
					     nm->lease_ms);
		if (rc == -ETIMEDOUT) {
			cogw_log(COGW_LOG_WARNING,
				 "reload: line %s is busy; it applies the new access rules when it "
				 "loops again",
				 line_name(d->lines[i]));
		} else if (rc < 0) {
			all = false;
			cogw_log(COGW_LOG_ERR,
				 "reload: line %s did not take the new access rules: %s",
				 line_name(d->lines[i]), strerror(-rc));
		}
	}
	if (!all)
		return; /* keep the old values so that the next reload retries */
	cogw_log(COGW_LOG_INFO, "reload: mailbox access: %zu rule%s, default %s, lease %u ms",
		 nm->n_rules, nm->n_rules == 1 ? "" : "s", mbx_access_to_string(nm->default_access),
		 nm->lease_ms);
	d->cfg.mailbox.n_rules = nm->n_rules;
	memcpy(d->cfg.mailbox.rules, nm->rules, nm->n_rules * sizeof nm->rules[0]);
	d->cfg.mailbox.default_access = nm->default_access;
	d->cfg.mailbox.lease_ms = nm->lease_ms;
}

/* lines[].rt at run time: the thread's scheduling and CPU. */
static void apply_rt_reload(daemon_state *d, const cogw_config *next)
{
	for (size_t i = 0; i < d->n_lines; i++) {
		cogw_rt_config *a = &d->cfg.lines[i].rt;
		const cogw_rt_config *b = &next->lines[i].rt;
		if (a->priority == b->priority && a->cpu == b->cpu)
			continue;
		int rc = line_set_rt(d->lines[i], b->priority, b->cpu);
		if (rc < 0) {
			cogw_log(COGW_LOG_ERR,
				 "reload: lines[%zu].rt: priority %d, cpu %d not applied: %s; the "
				 "line keeps priority %d, cpu %d",
				 i, b->priority, b->cpu, strerror(-rc), a->priority, a->cpu);
			continue;
		}
		cogw_log(COGW_LOG_INFO, "reload: line %s: rt priority %d -> %d, cpu %d -> %d",
			 line_name(d->lines[i]), a->priority, b->priority, a->cpu, b->cpu);
		*a = *b;
	}
}

/* lines[].heartbeat_consumers at run time: each changed 1016h entry. The
 * entries of listed nodes are their heartbeat_ms, set by the node changes
 * (applied first: a node removed and kept as a consumer is consumed). */
static void apply_consumers_reload(daemon_state *d, const cogw_config *next)
{
	for (size_t i = 0; i < d->n_lines; i++) {
		uint16_t *was = d->consumers_in_force[i], now[128];
		const cogw_node *node[128];
		(void)cogw_config_consumers(&next->lines[i], now);
		cogw_nodes_by_id(&next->lines[i], node);
		for (unsigned id = 1; id < 128; id++) {
			int rc;
			if (was[id] == now[id] || node[id]) {
				was[id] = now[id];
				continue;
			}
			if ((rc = line_request_consumer(d->lines[i], (uint8_t)id, now[id])) < 0) {
				cogw_log(COGW_LOG_ERR,
					 "reload: lines[%zu].heartbeat_consumers: node %u not "
					 "applied: %s",
					 i, id, strerror(-rc));
				continue;
			}
			cogw_log(COGW_LOG_INFO,
				 "reload: line %s: heartbeat of node %u consumed: %u -> %u ms",
				 line_name(d->lines[i]), id, was[id], now[id]);
			was[id] = now[id];
		}
	}
}

/* The line's part of one added, changed or removed node. */
static line_node_set node_set_of(const cogw_node_change *ch)
{
	static const uint8_t ops[] = { [COGW_NODE_ADDED] = MBX_NODE_ADD,
				       [COGW_NODE_CHANGED] = MBX_NODE_CHANGE,
				       [COGW_NODE_REMOVED] = MBX_NODE_REMOVE };
	const cogw_node *n = ch->node;
	line_node_set set = { .req = { .node = ch->id, .op = ops[ch->kind] }, .as_file = true };

	if (ch->kind == COGW_NODE_REMOVED)
		return set;
	set.req.flags = (uint8_t)((n->keep_op ? MBX_NODE_F_KEEP_OP : 0) |
				  (n->config.store ? MBX_NODE_F_STORE : 0));
	set.req.target_state = n->target_state;
	set.req.pdo = n->pdo;
	set.req.heartbeat_ms = n->heartbeat_ms;
	set.req.assignment = n->assignment;
	memcpy(set.req.identity, n->identity, sizeof set.req.identity);
	set.req.date = n->config.verify ? n->config.date : 0;
	set.req.time = n->config.verify ? n->config.time : 0;
	set.cdcf = n->config.cdcf_len ? n->config.cdcf : NULL;
	set.cdcf_len = (uint32_t)n->config.cdcf_len;
	set.types = n->types;
	set.n_types = n->n_types;
	return set;
}

/* Why a line did not take a node change, for the log. */
static const char *node_refusal_text(int rc)
{
	switch (rc) {
	case -EAGAIN:
		return "the network boot runs (or the manager is not the NMT master now): "
		       "send SIGHUP again when it has ended";
	case -EBUSY:
		return "a program download to it runs: reload when it has ended";
	default:
		return strerror(-rc);
	}
}

/* Line i's node changes, one by one; what a line took is in force. */
static bool apply_nodes_reload(daemon_state *d, size_t i, const cogw_node_diff *nd)
{
	static const char *const done[] = { "?", "added", "changed", "removed" };
	for (size_t k = 0; k < nd->n; k++) {
		const cogw_node_change *ch = &nd->change[k];
		line_node_set set = node_set_of(ch);
		int rc = line_request_node(d->lines[i], &set);
		char path[48];

		if (ch->kind == COGW_NODE_REMOVED)
			snprintf(path, sizeof path, "lines[%zu].nodes", i);
		else
			snprintf(path, sizeof path, "lines[%zu].nodes[%zu]", i, ch->index);
		if (rc < 0) {
			cogw_log(COGW_LOG_ERR, "reload: %s: node %u not %s: %s", path, ch->id,
				 done[ch->kind], node_refusal_text(rc));
			continue;
		}
		cogw_log(COGW_LOG_NOTICE, "reload: %s: node %u %s", path, ch->id, done[ch->kind]);
		d->nodes_in_force[i][ch->id] = ch->kind == COGW_NODE_REMOVED ? NULL : ch->node;
	}
	return nd->n > 0;
}

/* Everything of `next` that needs a restart, by JSON path, into what
 * (and the node changes of each line into nd): true when nothing does. */
static bool reload_acceptable(daemon_state *d, const cogw_config *next, cogw_node_diff *nd,
			      char *what, size_t len)
{
	bool ok = cogw_config_reload_check(&d->cfg, next, what, len);

	for (size_t i = 0; ok && i < d->n_lines; i++)
		if (!cogw_config_node_diff(d->nodes_in_force[i], &d->cfg.lines[i], &next->lines[i],
					   i, &nd[i])) {
			size_t used = strlen(what);
			snprintf(what + used, len - used, "%s%s", used ? "; " : "", nd[i].what);
			ok = false;
		}
	return ok;
}

/* Keep a reload's configuration while a line refers to it. */
static bool keep_config(daemon_state *d, cogw_config *next)
{
	cogw_config **k = realloc(d->kept, (d->n_kept + 1) * sizeof *k);
	if (!k)
		return false;
	d->kept = k;
	d->kept[d->n_kept++] = next;
	return true;
}

static void reload_refused(cogw_config *next, cogw_node_diff *nd)
{
	if (next)
		cogw_config_free(next);
	free(next);
	free(nd);
	sd_notify(0, "READY=1");
}

/*
 * SIGHUP: the file loaded and validated whole; refused, with every key
 * that needs a restart named by its JSON path, unless all of it can change
 * at run time; then applied key by key (docs/config.md "Reload"): the
 * heartbeat producer, the mailbox's access, the lines' scheduling, the
 * heartbeat consumers and the nodes of each line, each on its line thread.
 */
static void reload(daemon_state *d)
{
	sd_notify(0, "RELOADING=1");
	cogw_config *next = calloc(1, sizeof *next);
	cogw_node_diff *nd = calloc(d->n_lines ? d->n_lines : 1, sizeof *nd);
	char what[4096] = "";
	bool used = false;

	if (!next || !nd || load_config(d, next) < 0) {
		cogw_log(COGW_LOG_ERR,
			 "reload refused: the configuration has errors; keeping the running one");
		return reload_refused(next, nd);
	}
	if (!reload_acceptable(d, next, nd, what, sizeof what)) {
		cogw_log(COGW_LOG_ERR,
			 "reload refused: %s; the running configuration stays in force", what);
		return reload_refused(next, nd);
	}
	for (size_t i = 0; i < d->n_lines; i++)
		if (next->lines[i].heartbeat_ms != d->cfg.lines[i].heartbeat_ms) {
			line_request_hb_producer(d->lines[i], next->lines[i].heartbeat_ms);
			cogw_log(COGW_LOG_INFO, "reload: line %s heartbeat %u -> %u ms",
				 line_name(d->lines[i]), d->cfg.lines[i].heartbeat_ms,
				 next->lines[i].heartbeat_ms);
			d->cfg.lines[i].heartbeat_ms = next->lines[i].heartbeat_ms;
		}
	apply_access_reload(d, next);
	apply_rt_reload(d, next);
	for (size_t i = 0; i < d->n_lines; i++)
		used |= apply_nodes_reload(d, i, &nd[i]);
	apply_consumers_reload(d, next);
	free(nd);
	if (!used) {
		cogw_config_free(next);
		free(next);
	} else if (!keep_config(d, next)) {
		/* the lines refer to its nodes' types: it must stay */
		cogw_log(COGW_LOG_WARNING, "reload: out of memory listing the configuration the "
					   "lines now refer to; it stays allocated");
	}
	sd_notify(0, "READY=1");
}

static int wait_lines_up(daemon_state *d)
{
	uint64_t until = line_now_us() + STARTUP_TIMEOUT_US;
	for (;;) {
		size_t up = 0;
		for (size_t i = 0; i < d->n_lines; i++)
			up += line_is_up(d->lines[i]);
		if (up == d->n_lines)
			return 0;
		if (line_now_us() > until) {
			cogw_log(COGW_LOG_ERR, "only %zu of %zu lines came up", up, d->n_lines);
			return -ETIMEDOUT;
		}
		poll(NULL, 0, 5);
	}
}

/* A signal from the signalfd: true when it stops the daemon. */
static bool on_signal(daemon_state *d)
{
	struct signalfd_siginfo si;

	if (read(d->sigfd, &si, sizeof si) != (ssize_t)sizeof si)
		return false;
	switch (si.ssi_signo) {
	case SIGTERM:
	case SIGINT:
		cogw_log(COGW_LOG_NOTICE, "%s: stopping", strsignal((int)si.ssi_signo));
		return true;
	case SIGHUP:
		reload(d);
		break;
	case SIGUSR2:
		if (d->cfg.debug_stall_signal && d->n_lines)
			line_request_stall(d->lines[0],
					   d->cfg.debug_stall_ms ? d->cfg.debug_stall_ms : 5000);
		else
			cogw_log(COGW_LOG_NOTICE, "SIGUSR2 ignored (debug.stall_signal is off)");
		break;
	}
	return false;
}

static int run(daemon_state *d)
{
	char status[1024];
	uint64_t period = d->watchdog_usec ? d->watchdog_usec / 4 : 1000000u;
	if (period > 1000000u)
		period = 1000000u;
	uint64_t next_tick = 0;
	for (;;) {
		uint64_t now = line_now_us();
		if (now >= next_tick) {
			watchdog_tick(d, now);
			status_line(d, status, sizeof status);
			sd_notifyf(0, "STATUS=%s", status);
			next_tick = now + period;
		}
		struct pollfd pfd[2] = { { .fd = d->sigfd, .events = POLLIN },
					 { .fd = d->wakefd, .events = POLLIN } };
		int wait_ms = (int)((next_tick - now) / 1000u) + 1;
		if (poll(pfd, 2, wait_ms) < 0 && errno != EINTR)
			return -errno;
		if (pfd[1].revents & POLLIN) {
			uint64_t v;
			ssize_t r = read(d->wakefd, &v, sizeof v);
			(void)r;
			for (size_t i = 0; i < d->n_lines; i++)
				line_store_service(d->lines[i]);
		}
		if ((pfd[0].revents & POLLIN) && on_signal(d))
			return 0;
	}
}

#define ARGS_GO_ON (-1) /* parse_args: start the daemon */

/* The command line; returns ARGS_GO_ON or the exit code to stop with. */
static int parse_args(daemon_state *d, int argc, char **argv, bool *check_only)
{
	static const struct option opts[] = {
		{ "config", required_argument, NULL, 'c' },
		{ "state-dir", required_argument, NULL, 's' },
		{ "check", no_argument, NULL, 't' },
		{ "print-default", no_argument, NULL, 'P' },
		{ "verbose", no_argument, NULL, 'v' },
		{ "help", no_argument, NULL, 'h' },
		{ NULL, 0, NULL, 0 },
	};
	int c;

	while ((c = getopt_long(argc, argv, "c:s:tvh", opts, NULL)) != -1) {
		switch (c) {
		case 'c':
			d->config_path = optarg;
			break;
		case 's':
			d->state_dir_override = optarg;
			break;
		case 't':
			*check_only = true;
			break;
		case 'P':
			fputs(cogw_default_config_json, stdout);
			return 0;
		case 'v':
			cogw_log_set_max_level(COGW_LOG_DEBUG);
			break;
		case 'h':
			usage(stdout);
			return 0;
		default:
			usage(stderr);
			return 2;
		}
	}
	if (optind < argc) {
		fprintf(stderr, "cogwd: unexpected argument '%s'\n", argv[optind]);
		usage(stderr);
		return 2;
	}
	return ARGS_GO_ON;
}

/* What the system must allow before any line starts: the mailbox's
 * queue limits, the state directory, locked memory. */
static int prepare_system(const daemon_state *d)
{
	char err[512];

	if (mbx_check_system_limits(d->cfg.mailbox.depth, d->cfg.mailbox.msg_size, err,
				    sizeof err) < 0) {
		cogw_log(COGW_LOG_ERR, "%s", err);
		return -1;
	}
	if (prepare_state_dir(d->cfg.state_dir) < 0)
		return -1;
	/* MCL_ONFAULT: pages are locked as they are first touched, not when
	 * mapped. The transfer buffers are sized for the largest transfer
	 * (max_transfer each, several per line): locking them all up front
	 * pinned 1.2 GB for max_transfer 64 MiB on 3 lines, while
	 * only what transfers actually use needs to stay in RAM. Everything
	 * the real-time path touches at start-up is locked at once. */
	if (d->cfg.mlockall && mlockall(MCL_CURRENT | MCL_FUTURE | MCL_ONFAULT) != 0 &&
	    mlockall(MCL_CURRENT | MCL_FUTURE) != 0)
		cogw_log(COGW_LOG_WARNING, "mlockall not permitted (%s): memory may be paged out",
			 strerror(errno));
	return 0;
}

static int open_signals(daemon_state *d)
{
	sigset_t mask;

	sigemptyset(&mask);
	sigaddset(&mask, SIGTERM);
	sigaddset(&mask, SIGINT);
	sigaddset(&mask, SIGHUP);
	sigaddset(&mask, SIGUSR2);
	/* blocked before any thread starts, so every thread inherits it and
	 * only the signalfd sees these signals */
	pthread_sigmask(SIG_BLOCK, &mask, NULL);
	signal(SIGPIPE, SIG_IGN);
	d->sigfd = signalfd(-1, &mask, SFD_CLOEXEC);
	d->wakefd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
	if (d->sigfd < 0 || d->wakefd < 0) {
		cogw_log(COGW_LOG_ERR, "signalfd/eventfd: %s", strerror(errno));
		return -1;
	}
	return 0;
}

static int check_watchdog(daemon_state *d)
{
	if (sd_watchdog_enabled(0, &d->watchdog_usec) <= 0)
		d->watchdog_usec = 0;
	/* An idle line wakes every watchdog_check_ms/2 to check in, and a
	 * ping is withheld when a line has not checked in for half the
	 * watchdog period: a check period that does not fit would stop the
	 * pings of a healthy idle line (watchdog_check_ms 60000 under
	 * WatchdogSec=5s). Refused, with what would fit. */
	if (d->watchdog_usec && (uint64_t)d->cfg.watchdog_check_ms * 1000u > d->watchdog_usec / 2) {
		cogw_log(COGW_LOG_ERR,
			 "watchdog_check_ms %u does not fit the systemd watchdog period of %llu "
			 "ms: an idle "
			 "line checks in every watchdog_check_ms/2 and must do so within half the "
			 "period; "
			 "use at most %llu",
			 d->cfg.watchdog_check_ms, (unsigned long long)(d->watchdog_usec / 1000u),
			 (unsigned long long)(d->watchdog_usec / 2000u));
		return -1;
	}
	return 0;
}

/* The extensions and the lines, started and up. */
static int start_lines(daemon_state *d)
{
	if (cogwd_exts_setup(&d->exts, &d->cfg) < 0 || create_lines(d) < 0)
		return -1;
	for (size_t i = 0; i < d->n_lines; i++)
		if (line_start(d->lines[i]) < 0)
			return -1;
	return wait_lines_up(d);
}

static void announce_ready(daemon_state *d)
{
	char status[1024];

	log_memory(d);
	status_line(d, status, sizeof status);
	sd_notifyf(0, "READY=1\nSTATUS=%s", status);
	cogw_log(COGW_LOG_NOTICE, "ready: %zu line%s (%s), mailbox instance '%s'%s", d->n_lines,
		 d->n_lines == 1 ? "" : "s", d->cfg.source, d->cfg.mailbox.instance,
		 d->watchdog_usec ? ", systemd watchdog on" : "");
}

int main(int argc, char **argv)
{
	daemon_state d;
	memset(&d, 0, sizeof d);
	d.sigfd = d.wakefd = -1;
	bool check_only = false;
	if (cogw_version_asked("cogwd", argc, argv))
		return 0;
	int rc = parse_args(&d, argc, argv, &check_only);
	if (rc != ARGS_GO_ON)
		return rc;
	cogw_log_use_prefix(getenv("JOURNAL_STREAM") || getenv("NOTIFY_SOCKET"));

	if (load_config(&d, &d.cfg) < 0)
		return 1;
	for (size_t i = 0; i < d.cfg.n_lines; i++) {
		cogw_nodes_by_id(&d.cfg.lines[i], d.nodes_in_force[i]);
		(void)cogw_config_consumers(&d.cfg.lines[i], d.consumers_in_force[i]);
	}
	if (check_only) {
		printf("%s: configuration is valid (%zu lines)\n", d.cfg.source, d.cfg.n_lines);
		cogw_config_free(&d.cfg);
		return 0;
	}

	rc = 1;
	if (prepare_system(&d) == 0 && open_signals(&d) == 0 && check_watchdog(&d) == 0 &&
	    start_lines(&d) == 0) {
		announce_ready(&d);
		rc = run(&d) < 0 ? 1 : 0;
		sd_notify(0, "STOPPING=1");
	}
	for (size_t i = 0; i < d.n_lines; i++)
		line_destroy(d.lines[i]);
	for (size_t i = 0; i < COGW_LINES_MAX; i++)
		co_pdo_layout_destroy(d.pdo_layouts[i]);
	cogwd_exts_teardown(&d.exts);
	for (size_t i = 0; i < d.n_kept; i++) {
		cogw_config_free(d.kept[i]);
		free(d.kept[i]);
	}
	free(d.kept);
	cogw_config_free(&d.cfg);
	if (d.sigfd >= 0)
		close(d.sigfd);
	if (d.wakefd >= 0)
		close(d.wakefd);
	return rc;
}
