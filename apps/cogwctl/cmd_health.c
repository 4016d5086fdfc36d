/* SPDX-License-Identifier: MIT */
/*
 * cogwctl health: the bus health of a line (docs/troubleshooting.md): the
 * controller state, the fault episodes and their counters, and their reset.
 * `cogwctl status` prints the summary line from here too.
 */
#include <inttypes.h>
#include <string.h>

#include "apps/cogwctl/ctl.h"
#include "mailbox/cogw_health.h"

static void age_text(uint32_t age_ms, char *buf, size_t len)
{
	if (age_ms == UINT32_MAX)
		snprintf(buf, len, "never");
	else
		snprintf(buf, len, "%" PRIu32 ".%" PRIu32 " s ago", age_ms / 1000u,
			 age_ms % 1000u / 100u);
}

void ctl_health_summary_text(const mbx_line_health *hl)
{
	char active[160] = "";
	size_t used = 0;
	uint32_t episodes = 0;
	for (unsigned i = 0; i < MBX_FAULT_COUNT; i++) {
		episodes += hl->fault[i].episodes;
		if (hl->fault[i].active && used < sizeof active)
			used += (size_t)snprintf(active + used, sizeof active - used, "%s%s",
						 used ? ", " : "", mbx_fault_to_string(i));
	}
	printf("  health: %s; %" PRIu32 " fault episode%s counted (cogwctl health)\n",
	       used ? active : "no fault", episodes, episodes == 1 ? "" : "s");
}

void ctl_health_json(cJSON *o, const mbx_line_health *hl)
{
	cJSON_AddStringToObject(o, "can_state", mbx_can_state_to_string(hl->can_state));
	cJSON_AddNumberToObject(o, "tx_error_counter", hl->tec);
	cJSON_AddNumberToObject(o, "rx_error_counter", hl->rec);
	cJSON_AddNumberToObject(o, "restarts", hl->restarts);
	cJSON_AddNumberToObject(o, "id_conflict_quiet_ms", hl->id_collision_quiet_ms);
	cJSON_AddNumberToObject(o, "fault_quiet_ms", hl->lost_quiet_ms);
	cJSON_AddNumberToObject(o, "rx_overflow_drops", (double)hl->rx_overflow_drops);
	cJSON_AddNumberToObject(o, "tx_dropped", (double)hl->tx_dropped);
	cJSON_AddNumberToObject(o, "tx_errors", (double)hl->tx_errors);
	cJSON_AddNumberToObject(o, "tx_queued_max", (double)hl->tx_queued_max);
	cJSON_AddNumberToObject(o, "reopens", hl->reopens);
	cJSON_AddNumberToObject(o, "last_outage_ms", hl->last_outage_ms);
	cJSON *faults = cJSON_AddObjectToObject(o, "faults");
	for (unsigned i = 0; i < MBX_FAULT_COUNT; i++) {
		const mbx_fault_counters *fc = &hl->fault[i];
		cJSON *f = cJSON_AddObjectToObject(faults, mbx_fault_to_string(i));
		cJSON_AddBoolToObject(f, "active", fc->active);
		cJSON_AddNumberToObject(f, "episodes", fc->episodes);
		cJSON_AddNumberToObject(f, "occurrences", fc->occurrences);
		if (fc->age_ms == UINT32_MAX)
			cJSON_AddNullToObject(f, "last_ms_ago");
		else
			cJSON_AddNumberToObject(f, "last_ms_ago", fc->age_ms);
		if (i == MBX_FAULT_ID_COLLISION && fc->occurrences)
			cJSON_AddNumberToObject(f, "state_heard", fc->info);
	}
}

static void health_text(unsigned line, const mbx_line_health *hl)
{
	printf("line %u: CAN %s (tx errors %u, rx errors %u), %" PRIu32
	       " restart%s after bus-off\n",
	       line, mbx_can_state_to_string(hl->can_state), hl->tec, hl->rec, hl->restarts,
	       hl->restarts == 1 ? "" : "s");
	printf("  frames: rx lost %" PRIu64 " (socket), tx dropped %" PRIu64
	       " (queue full), tx refused %" PRIu64 " (kernel), tx queue high-water %" PRIu64 "\n",
	       hl->rx_overflow_drops, hl->tx_dropped, hl->tx_errors, hl->tx_queued_max);
	printf("  %-13s  %-6s  %8s  %11s  %s\n", "fault", "now", "episodes", "occurrences", "last");
	for (unsigned i = 0; i < MBX_FAULT_COUNT; i++) {
		const mbx_fault_counters *fc = &hl->fault[i];
		char last[32];
		age_text(fc->age_ms, last, sizeof last);
		printf("  %-13s  %-6s  %8" PRIu32 "  %11" PRIu32 "  %s\n", mbx_fault_to_string(i),
		       fc->active ? "ACTIVE" : "-", fc->episodes, fc->occurrences, last);
	}
	printf("  interface: last outage %" PRIu32 " ms, %" PRIu32 " new socket%s after it was "
	       "created again\n",
	       hl->last_outage_ms, hl->reopens, hl->reopens == 1 ? "" : "s");
	printf("  quiet times: node-ID conflict %" PRIu32 " ms, lost frames %" PRIu32 " ms\n",
	       hl->id_collision_quiet_ms, hl->lost_quiet_ms);
}

static int show(ctl *c, cogw *h, unsigned line, cJSON *arr)
{
	char ctx[48];
	mbx_line_health hl;
	snprintf(ctx, sizeof ctx, "health of line %u", line);
	int rc = cogw_line_health(h, line, &hl, c->timeout_ms);
	if (rc < 0)
		return ctl_fail(c, rc, 0, ctx);
	if (arr) {
		cJSON *o = cJSON_CreateObject();
		cJSON_AddNumberToObject(o, "line", line);
		ctl_health_json(o, &hl);
		cJSON_AddItemToArray(arr, o);
	} else {
		health_text(line, &hl);
	}
	return 0;
}

static int reset(ctl *c, cogw *h, unsigned line)
{
	char ctx[48];
	snprintf(ctx, sizeof ctx, "health reset of line %u", line);
	int rc = cogw_line_health_reset(h, line, c->timeout_ms);
	if (rc < 0)
		return ctl_fail(c, rc, 0, ctx);
	if (c->json) {
		cJSON *o = cJSON_CreateObject();
		cJSON_AddBoolToObject(o, "ok", true);
		cJSON_AddNumberToObject(o, "line", line);
		ctl_json_print(o);
	} else {
		printf("line %u: bus health counters reset\n", line);
	}
	return 0;
}

static int run(ctl *c, int argc, char **argv)
{
	const char *pos[MBX_LINES_MAX];
	int n_pos, ex = 0;
	int rc = ctl_parse(c, argc, argv, NULL, pos, MBX_LINES_MAX, &n_pos);
	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(&ctl_cmd_health);
	if (n_pos != 2 || strcmp(pos[1], "reset"))
		return ctl_each_line(c, pos, n_pos, show);
	unsigned line;
	if (ctl_arg_line(c, pos[0], &line) < 0)
		return CTL_EXIT_USAGE;
	cogw *h = ctl_handle(c, &ex);
	return h ? reset(c, h, line) : ex;
}

const ctl_cmd ctl_cmd_health = {
	.name = "health",
	.synopsis = "  health [LINE...] | health LINE reset     bus health: faults, counters\n",
	.help = "usage: cogwctl health [LINE...]\n"
		"       cogwctl health LINE reset\n"
		"\n"
		"The bus health of every line (or the lines given): the CAN controller state and\n"
		"its error counters, restarts after bus-off, frames lost on receive and refused\n"
		"on transmit, and per fault (id-collision, warning, passive, bus-off, rx-overrun,\n"
		"tx-lost, tx-pressure, link-down) whether an episode runs now, the episodes and "
		"occurrences\n"
		"counted and when the last one was. docs/troubleshooting.md says what each one\n"
		"means and what to check on the cable.\n"
		"\n"
		"reset zeroes the counters of LINE (running episodes go on); it needs write "
		"rights.\n"
		"\n"
		"Examples:\n"
		"  cogwctl health\n"
		"  cogwctl health 0 --json\n"
		"  cogwctl health 0 reset\n",
	.run = run,
};
