/* SPDX-License-Identifier: MIT */
/*
 * cogwctl app (its watchdog part) / host: the application watchdog, the
 * hold on the daemon's own OPERATIONAL and host ready / not ready
 * (docs/application.md, "The application watchdog and host ready").
 * cmd_app.c owns the verb: it shows a line's watchdogs and counters from
 * here, and hands `app LINE essential|hold` over (running as an essential
 * client, keep-alives until a signal, or as a holder); `host` says ready
 * or not ready. `cogwctl status` prints the summary line from here too.
 */
#include <errno.h>
#include <inttypes.h>
#include <signal.h>
#include <string.h>
#include <time.h>

#include "apps/cogwctl/ctl.h"
#include "core/nmt.h"

static const char *wd_state_text(uint8_t s)
{
	return s == 1 ? "declared" : s == 2 ? "armed" : s == 3 ? "TRIPPED" : "?";
}

static const char *cs_text(uint32_t cs)
{
	return cs == CO_NMT_CS_ENTER_PREOP ? "pre-operational" : "stop";
}

void ctl_appwd_summary_text(const mbx_appwd_status *st)
{
	printf("  application: host %s, %u essential client%s, %" PRIu64 " watchdog trip%s%s\n",
	       st->host_ready ? "ready" : "NOT READY", st->n, st->n == 1 ? "" : "s", st->trips,
	       st->trips == 1 ? "" : "s", st->holders ? ", own node held out of OPERATIONAL" : "");
}

void ctl_appwd_json(cJSON *o, const mbx_appwd_status *st, const mbx_appwd_entry *wd)
{
	char set[160];
	cJSON_AddBoolToObject(o, "host_ready", st->host_ready);
	cJSON_AddStringToObject(o, "own_nmt_state", co_nmt_state_to_string(st->own_state));
	cJSON_AddNumberToObject(o, "holders", st->holders);
	cJSON_AddBoolToObject(o, "start_deferred", st->flags & MBX_APPWD_NMT_DEFERRED);
	mbx_appwd_reactions_format(st->configured, set, sizeof set);
	cJSON_AddStringToObject(o, "configured_reactions", set);
	cJSON_AddNumberToObject(o, "safe_outputs", st->safe_outputs);
	cJSON_AddBoolToObject(o, "nmt_master", st->nmt_master);
	cJSON_AddStringToObject(o, "not_ready_nmt", cs_text(st->not_ready_action));
	cJSON *cnt = cJSON_AddObjectToObject(o, "counters");
	cJSON_AddNumberToObject(cnt, "declared", (double)st->declared);
	cJSON_AddNumberToObject(cnt, "keepalives", (double)st->keepalives);
	cJSON_AddNumberToObject(cnt, "refused", (double)st->refused);
	cJSON_AddNumberToObject(cnt, "trips", (double)st->trips);
	cJSON_AddNumberToObject(cnt, "late_keepalives", (double)st->late_keepalives);
	cJSON_AddNumberToObject(cnt, "not_ready_episodes", (double)st->not_ready_episodes);
	cJSON_AddNumberToObject(cnt, "starts_refused", (double)st->starts_refused);
	if (st->last_client) {
		cJSON *t = cJSON_AddObjectToObject(o, "last_trip");
		cJSON_AddNumberToObject(t, "client", st->last_client);
		cJSON_AddNumberToObject(t, "pid", st->last_pid);
		mbx_appwd_reactions_format(st->last_done, set, sizeof set);
		cJSON_AddStringToObject(t, "done", set);
		cJSON_AddNumberToObject(t, "late_us", st->last_late_us);
		cJSON_AddNumberToObject(t, "ms_ago", (double)st->last_age_ms);
	}
	cJSON *arr = cJSON_AddArrayToObject(o, "watchdogs");
	for (unsigned i = 0; i < st->n; i++) {
		cJSON *w = cJSON_CreateObject();
		cJSON_AddNumberToObject(w, "client", wd[i].client);
		cJSON_AddNumberToObject(w, "pid", wd[i].pid);
		cJSON_AddNumberToObject(w, "interval_ms", wd[i].interval_ms);
		mbx_appwd_reactions_format(wd[i].reactions, set, sizeof set);
		cJSON_AddStringToObject(w, "reactions", set);
		cJSON_AddStringToObject(w, "state", wd_state_text(wd[i].state));
		cJSON_AddBoolToObject(w, "client_gone", wd[i].gone);
		cJSON_AddNumberToObject(w, "left_ms", wd[i].left_ms);
		cJSON_AddNumberToObject(w, "keepalives", (double)wd[i].keepalives);
		cJSON_AddItemToArray(arr, w);
	}
}

static void app_text(const mbx_appwd_status *st, const mbx_appwd_entry *wd)
{
	char set[160];
	printf("  host %s, own node %s%s, %u holder%s\n", st->host_ready ? "ready" : "NOT READY",
	       co_nmt_state_to_string(st->own_state),
	       st->flags & MBX_APPWD_NMT_DEFERRED ? " (start deferred)" : "", st->holders,
	       st->holders == 1 ? "" : "s");
	mbx_appwd_reactions_format(st->configured, set, sizeof set);
	printf("  configured reactions: %s; %u safe output%s; NMT master: %s; not ready sends "
	       "NMT %s\n",
	       set, st->safe_outputs, st->safe_outputs == 1 ? "" : "s",
	       st->nmt_master ? "yes" : "no", cs_text(st->not_ready_action));
	printf("  counters: %" PRIu64 " declared, %" PRIu64 " keep-alives, %" PRIu64
	       " refused, %" PRIu64 " trips, %" PRIu64 " keep-alives after a trip, %" PRIu64
	       " not-ready episodes, %" PRIu64 " starts refused\n",
	       st->declared, st->keepalives, st->refused, st->trips, st->late_keepalives,
	       st->not_ready_episodes, st->starts_refused);
	if (st->last_client) {
		mbx_appwd_reactions_format(st->last_done, set, sizeof set);
		printf("  last trip: client %" PRIu32 " (pid %" PRIu32 "), %" PRIu64
		       " ms ago, %" PRIu32 " us after its deadline: %s\n",
		       st->last_client, st->last_pid, st->last_age_ms, st->last_late_us, set);
	}
	for (unsigned i = 0; i < st->n; i++) {
		mbx_appwd_reactions_format(wd[i].reactions, set, sizeof set);
		printf("  essential client %" PRIu32 " (pid %" PRIu32 "%s): %s, %" PRIu32
		       " ms, %" PRIu32 " ms left, %" PRIu64 " keep-alives: %s\n",
		       wd[i].client, wd[i].pid, wd[i].gone ? ", gone" : "",
		       wd_state_text(wd[i].state), wd[i].interval_ms, wd[i].left_ms,
		       wd[i].keepalives, set);
	}
}

int ctl_appwd_show(ctl *c, cogw *h, unsigned line, cJSON *o)
{
	char ctx[48];
	mbx_appwd_status st;
	mbx_appwd_entry wd[MBX_APPWD_MAX];
	snprintf(ctx, sizeof ctx, "application status of line %u", line);
	int n = cogw_app_status(h, line, &st, wd, MBX_APPWD_MAX, c->timeout_ms);
	if (n < 0)
		return ctl_fail(c, n, 0, ctx);
	if (o)
		ctl_appwd_json(o, &st, wd);
	else
		app_text(&st, wd);
	return 0;
}

/* ---- running as an essential client or a holder ---------------------------- */

static volatile sig_atomic_t stop_requested;

static void on_signal(int sig)
{
	(void)sig;
	stop_requested = 1;
}

static void sleep_ms(unsigned ms)
{
	struct timespec ts = { .tv_sec = ms / 1000u, .tv_nsec = (long)(ms % 1000u) * 1000000L };
	nanosleep(&ts, NULL); /* a signal cuts it short: the loop looks at the flag */
}

static void catch_signals(void)
{
	struct sigaction sa = { .sa_handler = on_signal }; /* no SA_RESTART */
	sigemptyset(&sa.sa_mask);
	sigaction(SIGINT, &sa, NULL);
	sigaction(SIGTERM, &sa, NULL);
}

static void say(ctl *c, const char *what, unsigned line, const char *detail)
{
	if (c->json) {
		cJSON *o = cJSON_CreateObject();
		cJSON_AddStringToObject(o, "event", what);
		cJSON_AddNumberToObject(o, "line", line);
		if (detail)
			cJSON_AddStringToObject(o, "detail", detail);
		ctl_json_print(o);
	} else {
		printf("line %u: %s%s%s\n", line, what, detail ? ": " : "", detail ? detail : "");
	}
	fflush(stdout);
}

typedef struct essential_opts {
	uint32_t interval_ms, reactions;
	bool rearm;
} essential_opts;

static int declare(ctl *c, cogw *h, unsigned line, const essential_opts *o)
{
	mbx_appwd_resp r;
	char set[160], skipped[160], detail[360];
	int rc = cogw_app_watchdog(h, line, o->interval_ms, o->reactions, &r, c->timeout_ms);
	if (rc < 0)
		return ctl_fail(c, rc, 0, "app essential");
	mbx_appwd_reactions_format(r.reactions, set, sizeof set);
	mbx_appwd_reactions_format(r.unavailable, skipped, sizeof skipped);
	snprintf(detail, sizeof detail, "%" PRIu32 " ms, %s (cannot now: %s)", o->interval_ms, set,
		 r.unavailable ? skipped : "none");
	say(c, "essential", line, detail);
	return 0;
}

/* Keep-alives every interval/4 until a signal; a trip ends the run, or
 * with --rearm is acknowledged by declaring again. Withdraws at the end. */
static int essential(ctl *c, cogw *h, unsigned line, const essential_opts *o)
{
	unsigned period = o->interval_ms / 4u ? o->interval_ms / 4u : 1u;
	int rc = declare(c, h, line, o);
	catch_signals();
	while (!rc && !stop_requested) {
		int k = cogw_app_keepalive(h, line, c->timeout_ms);
		if (k == COGW_E_STATE && o->rearm) {
			say(c, "tripped", line, "declaring again");
			rc = declare(c, h, line, o);
			continue;
		}
		if (k == COGW_E_STATE) {
			say(c, "tripped", line, "the watchdog missed a keep-alive of this client");
			return CTL_EXIT_REFUSED;
		}
		if (k < 0)
			return ctl_fail(c, k, 0, "app keep-alive");
		sleep_ms(period);
	}
	if (rc)
		return rc;
	rc = cogw_app_watchdog(h, line, 0, 0, NULL, c->timeout_ms);
	if (rc < 0)
		return ctl_fail(c, rc, 0, "app withdraw");
	say(c, "withdrawn", line, NULL);
	return 0;
}

static int hold(ctl *c, cogw *h, unsigned line)
{
	mbx_appwd_nmt n;
	int rc = cogw_app_hold(h, line, 1, &n, c->timeout_ms);
	if (rc < 0)
		return ctl_fail(c, rc, 0, "app hold");
	say(c, "holding", line, co_nmt_state_to_string(n.state));
	catch_signals();
	while (!stop_requested)
		sleep_ms(1000);
	rc = cogw_app_hold(h, line, 0, &n, c->timeout_ms);
	if (rc < 0)
		return ctl_fail(c, rc, 0, "app ready");
	say(c, "ready", line, co_nmt_state_to_string(n.state));
	return 0;
}

static int essential_args(ctl *c, const char *interval, const char *react, essential_opts *o)
{
	uint64_t v;
	if (!interval)
		return ctl_usage_error(c, "app essential needs --interval MS");
	if (ctl_arg_uint(c, interval, "--interval", MBX_APPWD_INTERVAL_MAX_MS, &v) < 0)
		return CTL_EXIT_USAGE;
	if (v < MBX_APPWD_INTERVAL_MIN_MS)
		return ctl_usage_error(c, "--interval: at least %u ms", MBX_APPWD_INTERVAL_MIN_MS);
	o->interval_ms = (uint32_t)v;
	if (!react || !strcmp(react, "configured"))
		o->reactions = MBX_APPWD_R_CONFIGURED;
	else if (mbx_appwd_reactions_parse(react, &o->reactions) < 0)
		return ctl_usage_error(c, "--react: a list of emcy, nmt-preop, nmt-stop, "
					  "nmt-reset-comm, nmt-reset-node, hb-stop, safe-outputs");
	return 0;
}

bool ctl_appwd_wants(int argc, char **argv)
{
	for (int i = 1; i < argc; i++)
		if (!strcmp(argv[i], "essential") || !strcmp(argv[i], "hold"))
			return true;
	return false;
}

int ctl_appwd_run(ctl *c, int argc, char **argv, const ctl_cmd *cmd)
{
	const char *pos[MBX_LINES_MAX], *interval = NULL, *react = NULL;
	essential_opts o = { 0 };
	const ctl_opt opts[] = { { "--interval", true, &interval, NULL },
				 { "--react", true, &react, NULL },
				 { "--rearm", false, NULL, &o.rearm },
				 { NULL, false, NULL, NULL } };
	int n_pos, ex = 0;
	int rc = ctl_parse(c, argc, argv, opts, pos, MBX_LINES_MAX, &n_pos);
	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(cmd);
	if (n_pos != 2 || (strcmp(pos[1], "essential") && strcmp(pos[1], "hold")))
		return ctl_usage_error(c, "app LINE essential|hold");
	unsigned line;
	if (ctl_arg_line(c, pos[0], &line) < 0)
		return CTL_EXIT_USAGE;
	if (!strcmp(pos[1], "essential") && (rc = essential_args(c, interval, react, &o)))
		return rc;
	cogw *h = ctl_handle(c, &ex);
	if (!h)
		return ex;
	return !strcmp(pos[1], "hold") ? hold(c, h, line) : essential(c, h, line, &o);
}

/* ---- host ready / not ready ------------------------------------------------- */

static int host_run(ctl *c, int argc, char **argv)
{
	const char *pos[2];
	int n_pos, ex = 0;
	int rc = ctl_parse(c, argc, argv, NULL, pos, 2, &n_pos);
	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(&ctl_cmd_host);
	unsigned line;
	if (n_pos != 2 || (strcmp(pos[1], "ready") && strcmp(pos[1], "not-ready")))
		return ctl_usage_error(c, "host LINE ready|not-ready");
	if (ctl_arg_line(c, pos[0], &line) < 0)
		return CTL_EXIT_USAGE;
	cogw *h = ctl_handle(c, &ex);
	if (!h)
		return ex;
	bool ready = !strcmp(pos[1], "ready");
	rc = cogw_host_ready(h, line, ready, c->timeout_ms);
	if (rc < 0)
		return ctl_fail(c, rc, 0, "host");
	say(c, ready ? "host ready" : "host not ready", line, NULL);
	return 0;
}

const ctl_cmd ctl_cmd_host = {
	.name = "host",
	.synopsis = "  host LINE ready|not-ready                process data of a line on/off\n",
	.help = "usage: cogwctl host LINE ready|not-ready\n"
		"\n"
		"not-ready stops LINE's process data: the safe outputs are written (their TPDOs\n"
		"sent), the line's NMT master stops the network (or puts it into\n"
		"pre-operational, lines[].app.not_ready_nmt), the daemon's own node goes\n"
		"PRE-OPERATIONAL (its TPDOs stop) and requests for the line's nodes are refused\n"
		"(status STATE) until ready, which starts the network and the own node again.\n"
		"Needs write rights. docs/application.md has the details.\n"
		"\n"
		"Examples:\n"
		"  cogwctl host 0 not-ready\n"
		"  cogwctl host 0 ready\n",
	.run = host_run,
};
