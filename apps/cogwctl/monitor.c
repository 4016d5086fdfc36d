/* SPDX-License-Identifier: MIT */
/*
 * cogwctl monitor and raw send|dump: the live event stream of chosen lines
 * and classes, one line (or one JSON object) per event, until SIGINT,
 * --count or --duration.
 */
#include <ctype.h>
#include <inttypes.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "apps/cogwctl/ctl.h"
#include "core/swmgr.h"
#include "core/manager.h"
#include "core/emcy.h"
#include "core/nmt.h"
#include "core/sdo.h"

static volatile sig_atomic_t interrupted;

static void on_signal(int sig)
{
	(void)sig;
	interrupted = 1;
}

static double mono_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + (double)ts.tv_nsec / 1e9;
}

static const char *nmt_text(uint8_t s)
{
	return s == 0xFF ? "unknown" : co_nmt_state_to_string(s);
}

/* can-utils notation: 123#0102, 12345678#..., 123#R */
static void frame_text(const mbx_raw_frame *f, char *buf, size_t len)
{
	uint32_t id = f->id & 0x1FFFFFFFu;
	size_t off = (size_t)snprintf(
		buf, len, (f->id & MBX_RAW_EXT) ? "%08" PRIX32 "#" : "%03" PRIX32 "#", id);
	if (f->id & MBX_RAW_RTR) {
		if (f->len)
			snprintf(buf + off, len - off, "R%u", f->len);
		else
			snprintf(buf + off, len - off, "R");
		return;
	}
	for (unsigned i = 0; i < f->len && i < 8 && off + 3 < len; i++)
		off += (size_t)snprintf(buf + off, len - off, "%02X", f->data[i]);
}

static void pdo_value_text(const mbx_pdo_value *v, bool as_float, char *buf, size_t len)
{
	uint8_t n = v->len > 8 ? 8 : v->len;
	uint64_t u = 0;
	for (unsigned i = 0; i < n; i++)
		u |= (uint64_t)v->data[i] << (8 * i);
	if (as_float && n == 4) {
		char num[32]; /* the text that reads back to the same REAL32 */
		cogw_value_format(MBX_T_REAL32, v->data, 4, num, sizeof num);
		snprintf(buf, len, "%04X:%02X = %s", v->index, v->sub, num);
		return;
	}
	char *hex = ctl_hex_text(v->data, n, 8);
	snprintf(buf, len, "%04X:%02X = %s (%" PRIu64 ")", v->index, v->sub, hex, u);
	free(hex);
}

/* ---- one printer per event kind ---------------------------------------- */

/* What a printer writes: the text line's words and, with --json, the
 * event's own members of the JSON object (NULL without --json). */
typedef struct event_out {
	char *text;
	size_t len;
	cJSON *o;
} event_out;

typedef void (*event_printer)(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out);

/* The events that carry one node and its NMT state (mbx_ev_node): their
 * text, with "%u" the node and "%s" the state where the text names it. */
static const struct {
	uint16_t code;
	const char *text;
	bool with_state;
} node_events[] = {
	{ MBX_EV_BOOTUP, "node %u boot-up", false },
	{ MBX_EV_HB_STARTED, "node %u heartbeat started (%s)", true },
	{ MBX_EV_HB_LOST, "node %u heartbeat LOST", false },
	{ MBX_EV_GUARD_TOGGLE, "node %u guarding: toggle bit repeated (%s)", true },
	{ MBX_EV_LIFE_LOST, "our node %u: life guarding LOST", false },
	{ MBX_EV_LIFE_RESUMED, "our node %u: guarded again", false },
};

static void print_node_event(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	mbx_ev_node e;

	(void)spec;
	memcpy(&e, m->data, sizeof e);
	if (m->code == MBX_EV_NMT_STATE)
		snprintf(out->text, out->len, "node %u %s -> %s", e.node, nmt_text(e.prev),
			 nmt_text(e.state));
	for (size_t i = 0; i < sizeof node_events / sizeof node_events[0]; i++) {
		if (node_events[i].code != m->code)
			continue;
		if (node_events[i].with_state)
			snprintf(out->text, out->len, node_events[i].text, e.node,
				 nmt_text(e.state));
		else
			snprintf(out->text, out->len, node_events[i].text, e.node);
	}
	if (!out->o)
		return;
	cJSON_AddNumberToObject(out->o, "node", e.node);
	cJSON_AddStringToObject(out->o, "state", nmt_text(e.state));
	if (m->code == MBX_EV_NMT_STATE)
		cJSON_AddStringToObject(out->o, "prev", nmt_text(e.prev));
}

static void print_gw_sdo(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	static const char *const outcome[] = { "routed", "aborted", "timed out", "refused" };
	mbx_ev_gw_sdo e;
	char ab[96] = "", via[256];

	(void)spec;
	memcpy(&e, m->data, sizeof e);
	const char *oc = e.outcome < 4 ? outcome[e.outcome] : "?";
	if (e.abort)
		ctl_abort_text(e.abort, ab, sizeof ab);
	if (e.target_line == 0xFF)
		snprintf(via, sizeof via, "refused before leaving");
	else if (e.router)
		snprintf(via, sizeof via, "via line %u, router node %u", e.target_line, e.router);
	else
		snprintf(via, sizeof via, "via line %u", e.target_line);
	snprintf(out->text, out->len, "routed SDO to network %u node %u (%s): %s%s%s, %u frames",
		 e.net, e.node, via, oc, e.abort ? ", abort " : "", ab, e.frames);
	if (!out->o)
		return;
	cJSON_AddNumberToObject(out->o, "net", e.net);
	cJSON_AddNumberToObject(out->o, "node", e.node);
	cJSON_AddStringToObject(out->o, "outcome", oc);
	cJSON_AddNumberToObject(out->o, "abort", e.abort);
	if (e.target_line != 0xFF)
		cJSON_AddNumberToObject(out->o, "target_line", e.target_line);
	cJSON_AddNumberToObject(out->o, "router", e.router);
	cJSON_AddNumberToObject(out->o, "channel", e.channel);
	cJSON_AddNumberToObject(out->o, "frames", e.frames);
}

static void print_dup_node(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	mbx_ev_dup_node e;

	(void)spec;
	memcpy(&e, m->data, sizeof e);
	snprintf(out->text, out->len,
		 "node %u: two answers to one SDO request (%04X:%02X), %" PRIu32
		 " so far: two devices on this node-ID",
		 e.node, e.index, e.sub, e.count);
	if (!out->o)
		return;
	cJSON_AddNumberToObject(out->o, "node", e.node);
	cJSON_AddNumberToObject(out->o, "index", e.index);
	cJSON_AddNumberToObject(out->o, "sub", e.sub);
	cJSON_AddNumberToObject(out->o, "count", e.count);
	cJSON_AddNumberToObject(out->o, "abort", e.abort);
}

static void print_gw_emcy(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	mbx_ev_gw_emcy e;

	(void)spec;
	memcpy(&e, m->data, sizeof e);
	snprintf(out->text, out->len,
		 "EMCY %04X of node %u (network %u) forwarded to lines mask %04X", e.code,
		 e.src_node, e.src_net, e.lines);
	if (!out->o)
		return;
	cJSON_AddNumberToObject(out->o, "src_net", e.src_net);
	cJSON_AddNumberToObject(out->o, "src_node", e.src_node);
	cJSON_AddNumberToObject(out->o, "code", e.code);
	cJSON_AddNumberToObject(out->o, "lines", e.lines);
}

static void print_emcy(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	mbx_ev_emcy e;

	(void)spec;
	memcpy(&e, m->data, sizeof e);
	char *hex = ctl_hex_text(e.msef, 5, 5);
	const char *what = e.code ? co_emcy_code_to_string(e.code) : "error reset";
	snprintf(out->text, out->len, "node %u EMCY %04X (%s) register %02X data %s", e.node,
		 e.code, what, e.reg, hex);
	if (out->o) {
		cJSON_AddNumberToObject(out->o, "ts_us", (double)e.ts_us);
		cJSON_AddNumberToObject(out->o, "node", e.node);
		cJSON_AddNumberToObject(out->o, "code", e.code);
		cJSON_AddStringToObject(out->o, "code_text", what);
		cJSON_AddNumberToObject(out->o, "register", e.reg);
		cJSON_AddStringToObject(out->o, "data", hex);
	}
	free(hex);
}

static cJSON *pdo_value_json(const mbx_pdo_value *v)
{
	cJSON *jv = cJSON_CreateObject();
	uint8_t n = v->len > 8 ? 8 : v->len;
	char *hex = ctl_hex_text(v->data, n, 8);

	cJSON_AddNumberToObject(jv, "index", v->index);
	cJSON_AddNumberToObject(jv, "sub", v->sub);
	cJSON_AddStringToObject(jv, "hex", hex);
	free(hex);
	if (n == 4)
		ctl_json_add_real(jv, "r32", CO_T_REAL32, v->data);
	return jv;
}

static void print_pdo(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	mbx_ev_pdo e;
	char one[256];

	memcpy(&e, m->data, sizeof e);
	size_t off = (size_t)snprintf(out->text, out->len, "RPDO %u:", e.pdo);
	cJSON *vals = out->o ? cJSON_CreateArray() : NULL;
	for (unsigned i = 0; i < e.n && sizeof e + (i + 1) * sizeof(mbx_pdo_value) <= m->len; i++) {
		mbx_pdo_value v;
		memcpy(&v, m->data + sizeof e + i * sizeof v, sizeof v);
		pdo_value_text(&v, spec->as_float, one, sizeof one);
		if (off < out->len)
			off += (size_t)snprintf(out->text + off, out->len - off, " %s", one);
		if (vals)
			cJSON_AddItemToArray(vals, pdo_value_json(&v));
	}
	if (!out->o)
		return;
	cJSON_AddNumberToObject(out->o, "ts_us", (double)e.ts_us);
	cJSON_AddNumberToObject(out->o, "pdo", e.pdo);
	cJSON_AddItemToObject(out->o, "values", vals);
}

static void print_sdo_done(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	mbx_ev_sdo_done e;
	char ab[128] = "ok";

	(void)spec;
	memcpy(&e, m->data, sizeof e);
	if (e.abort)
		snprintf(ab, sizeof ab, "abort 0x%08" PRIX32 " (%s)", e.abort,
			 sdo_abort_to_string(e.abort));
	snprintf(out->text, out->len,
		 "node %u SDO %s %04X:%02X %" PRIu32 " bytes: %s (client %" PRIu32 ")", e.node,
		 e.upload ? "upload" : "download", e.index, e.sub, e.size, ab, e.client);
	if (!out->o)
		return;
	cJSON_AddNumberToObject(out->o, "node", e.node);
	cJSON_AddBoolToObject(out->o, "upload", e.upload);
	cJSON_AddNumberToObject(out->o, "index", e.index);
	cJSON_AddNumberToObject(out->o, "sub", e.sub);
	cJSON_AddNumberToObject(out->o, "size", e.size);
	cJSON_AddNumberToObject(out->o, "abort", e.abort);
	cJSON_AddNumberToObject(out->o, "client", e.client);
}

static void print_mgr_state(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	mbx_ev_mgr e;

	(void)spec;
	memcpy(&e, m->data, sizeof e);
	snprintf(out->text, out->len, "manager %s -> %s (flags %02X)",
		 co_mgr_state_to_string(e.prev), co_mgr_state_to_string(e.state), e.flags);
	if (!out->o)
		return;
	cJSON_AddNumberToObject(out->o, "node", e.node);
	cJSON_AddStringToObject(out->o, "state", co_mgr_state_to_string(e.state));
	cJSON_AddStringToObject(out->o, "prev", co_mgr_state_to_string(e.prev));
	cJSON_AddNumberToObject(out->o, "flags", e.flags);
}

/* The text of one boot step: a failed step with its status letter, the
 * configuration download's count, or the step passed. */
static void mgr_boot_text(const mbx_ev_mgr *e, char *text, size_t len)
{
	const char *step = co_mgr_step_to_string(e->step);

	if (e->status == 'J')
		/* the configuration download: value = the concise DCF entry */
		snprintf(text, len,
			 "node %u boot %s %04X:%02X FAILED: status J (%s), entry %" PRIu32
			 ", abort 0x%08" PRIX32 " (%s)",
			 e->node, step, e->index, e->sub, co_mgr_status_to_string(e->status),
			 e->value, e->abort, sdo_abort_to_string(e->abort));
	else if (e->status && e->status != 'L')
		snprintf(text, len,
			 "node %u boot %s %04X:%02X FAILED: status %c (%s), abort "
			 "0x%08" PRIX32 ", value 0x%08" PRIX32 " expected 0x%08" PRIX32,
			 e->node, step, e->index, e->sub, e->status,
			 co_mgr_status_to_string(e->status), e->abort, e->value, e->expected);
	else if (e->step == CO_MGR_STEP_SOFTWARE && e->index == CO_SWMGR_IDX_CONTROL &&
		 e->value != CO_SWMGR_PROG_STARTED)
		/* the program state seen although the software is not checked */
		snprintf(text, len,
			 "node %u boot software: its program does not run (1F51:01 = %" PRIu32
			 ", %s)",
			 e->node, e->value, co_swmgr_program_to_string((uint8_t)e->value));
	else if (e->step == CO_MGR_STEP_PDO_LAYOUT && e->abort)
		/* not a CiA 302-2 check: the boot goes on */
		snprintf(text, len,
			 "node %u boot pdo-layout: not learnt, %04X:%02X abort 0x%08" PRIX32
			 " (%s); the boot goes on",
			 e->node, e->index, e->sub, e->abort, sdo_abort_to_string(e->abort));
	else if (e->step == CO_MGR_STEP_PDO_LAYOUT)
		/* value: PDOs kept, TPDOs | RPDOs << 16; expected: those dropped */
		snprintf(text, len,
			 "node %u boot pdo-layout ok: %" PRIu32 " TPDOs, %" PRIu32
			 " RPDOs learnt by SDO (%" PRIu32 " and %" PRIu32
			 " beyond pdo_scan_max, not kept)",
			 e->node, e->value & 0xFFFFu, e->value >> 16, e->expected & 0xFFFFu,
			 e->expected >> 16);
	else if (e->step == CO_MGR_STEP_CONFIGURE && e->value)
		/* value: the concise DCF entries written */
		snprintf(text, len,
			 "node %u boot configure ok: %" PRIu32 " concise DCF entries downloaded",
			 e->node, e->value);
	else if (e->step == CO_MGR_STEP_CONFIGURE)
		snprintf(text, len,
			 "node %u boot configure ok: nothing downloaded (no configuration, or "
			 "1020h matches)",
			 e->node);
	else
		snprintf(text, len, "node %u boot %s%s%s", e->node, step,
			 e->status == 'L' ? " L (was operational)" : " ok",
			 e->done ? ": booted" : "");
}

static void print_mgr_boot(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	mbx_ev_mgr e;
	char st[2];

	(void)spec;
	memcpy(&e, m->data, sizeof e);
	mgr_boot_text(&e, out->text, out->len);
	if (!out->o)
		return;
	st[0] = e.status;
	st[1] = 0;
	cJSON_AddNumberToObject(out->o, "node", e.node);
	cJSON_AddStringToObject(out->o, "step", co_mgr_step_to_string(e.step));
	cJSON_AddStringToObject(out->o, "status", st);
	cJSON_AddNumberToObject(out->o, "abort", e.abort);
	cJSON_AddNumberToObject(out->o, "index", e.index);
	cJSON_AddNumberToObject(out->o, "sub", e.sub);
	cJSON_AddNumberToObject(out->o, "value", e.value);
	if (e.status == 'J')
		cJSON_AddNumberToObject(out->o, "entry", e.value);
	if (e.step == CO_MGR_STEP_PDO_LAYOUT && !e.abort) {
		cJSON_AddNumberToObject(out->o, "tpdos", e.value & 0xFFFFu);
		cJSON_AddNumberToObject(out->o, "rpdos", e.value >> 16);
		cJSON_AddNumberToObject(out->o, "tpdos_dropped", e.expected & 0xFFFFu);
		cJSON_AddNumberToObject(out->o, "rpdos_dropped", e.expected >> 16);
	}
	cJSON_AddNumberToObject(out->o, "expected", e.expected);
	cJSON_AddBoolToObject(out->o, "done", e.done);
	cJSON_AddBoolToObject(out->o, "mandatory", e.mandatory);
}

static void print_mgr_node(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	mbx_ev_mgr e;

	(void)spec;
	memcpy(&e, m->data, sizeof e);
	snprintf(out->text, out->len, "node %u %s (%" PRIu32 ")", e.node,
		 co_mgr_node_what_to_string(e.what), e.value);
	if (!out->o)
		return;
	cJSON_AddNumberToObject(out->o, "node", e.node);
	cJSON_AddStringToObject(out->o, "what", co_mgr_node_what_to_string(e.what));
	cJSON_AddNumberToObject(out->o, "value", e.value);
}

static void print_can_state(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	mbx_ev_can_state e;

	(void)spec;
	memcpy(&e, m->data, sizeof e);
	snprintf(out->text, out->len, "CAN %s -> %s (tx errors %u, rx errors %u)",
		 mbx_can_state_to_string(e.prev), mbx_can_state_to_string(e.state), e.tec, e.rec);
	if (!out->o)
		return;
	cJSON_AddStringToObject(out->o, "state", mbx_can_state_to_string(e.state));
	cJSON_AddStringToObject(out->o, "prev", mbx_can_state_to_string(e.prev));
}

static void print_comm_fault(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	mbx_ev_comm_fault e;

	(void)spec;
	memcpy(&e, m->data, sizeof e);
	snprintf(out->text, out->len, "%s %s (CAN %s, episode %u, %u occurrences)",
		 mbx_fault_to_string(e.fault), e.active ? "begins" : "is over",
		 mbx_can_state_to_string(e.can_state), e.episodes, e.occurrences);
	if (!out->o)
		return;
	cJSON_AddStringToObject(out->o, "fault", mbx_fault_to_string(e.fault));
	cJSON_AddBoolToObject(out->o, "active", e.active);
	cJSON_AddStringToObject(out->o, "can_state", mbx_can_state_to_string(e.can_state));
	cJSON_AddNumberToObject(out->o, "episodes", e.episodes);
	cJSON_AddNumberToObject(out->o, "occurrences", e.occurrences);
	if (e.fault == MBX_FAULT_ID_COLLISION)
		cJSON_AddNumberToObject(out->o, "state_heard", e.info);
}

static void print_unknown_node(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	mbx_ev_unknown_node e;
	const mbx_node_ident *id = &e.ident;

	(void)spec;
	memcpy(&e, m->data, sizeof e);
	snprintf(out->text, out->len,
		 "node %u not configured (%s): 1000h %08X, 1018h %08X/%08X/%08X%s; %s: %s",
		 id->node, mbx_ident_source_to_string(id->source), (unsigned)id->device_type,
		 (unsigned)id->vendor_id, (unsigned)id->product_code, (unsigned)id->revision,
		 id->flags & MBX_IDENT_IDENTITY ? "" : " (not read)",
		 mbx_unknown_policy_to_string(e.policy), mbx_unknown_action_to_string(e.action));
	if (!out->o)
		return;
	cJSON_AddNumberToObject(out->o, "node", id->node);
	cJSON_AddStringToObject(out->o, "source", mbx_ident_source_to_string(id->source));
	cJSON_AddBoolToObject(out->o, "identity", id->flags & MBX_IDENT_IDENTITY);
	cJSON_AddNumberToObject(out->o, "device_type", id->device_type);
	cJSON_AddNumberToObject(out->o, "vendor_id", id->vendor_id);
	cJSON_AddNumberToObject(out->o, "product_code", id->product_code);
	cJSON_AddNumberToObject(out->o, "revision", id->revision);
	cJSON_AddNumberToObject(out->o, "serial", id->serial);
	cJSON_AddStringToObject(out->o, "policy", mbx_unknown_policy_to_string(e.policy));
	cJSON_AddStringToObject(out->o, "action", mbx_unknown_action_to_string(e.action));
	cJSON_AddNumberToObject(out->o, "reported", e.reported);
}

static void print_raw(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	mbx_ev_raw e;
	char frame[256];

	(void)spec;
	memcpy(&e, m->data, sizeof e);
	frame_text(&e.frame, frame, sizeof frame);
	snprintf(out->text, out->len, "%s", frame);
	if (!out->o)
		return;
	cJSON_AddNumberToObject(out->o, "ts_us", (double)e.ts_us);
	cJSON_AddStringToObject(out->o, "frame", frame);
	cJSON_AddNumberToObject(out->o, "id", e.frame.id & 0x1FFFFFFFu);
	cJSON_AddBoolToObject(out->o, "ext", e.frame.id & MBX_RAW_EXT);
	cJSON_AddBoolToObject(out->o, "rtr", e.frame.id & MBX_RAW_RTR);
}

static void print_od_written(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	mbx_ev_od_written e;

	(void)spec;
	memcpy(&e, m->data, sizeof e);
	snprintf(out->text, out->len, "own OD %04X:%02X written (%" PRIu32 " bytes)", e.index,
		 e.sub, e.size);
	if (!out->o)
		return;
	cJSON_AddNumberToObject(out->o, "index", e.index);
	cJSON_AddNumberToObject(out->o, "sub", e.sub);
	cJSON_AddNumberToObject(out->o, "size", e.size);
}

static void print_overflow(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	mbx_ev_overflow e;

	(void)spec;
	memcpy(&e, m->data, sizeof e);
	snprintf(out->text, out->len,
		 "our event queue overflowed: %" PRIu32 " events and %" PRIu32
		 " responses were lost",
		 e.dropped_events, e.dropped_responses);
	if (!out->o)
		return;
	cJSON_AddNumberToObject(out->o, "dropped_events", e.dropped_events);
	cJSON_AddNumberToObject(out->o, "dropped_responses", e.dropped_responses);
}

/* Every event kind cogwctl knows (mailbox/proto.h, docs/cogwctl.md
 * "monitor"); another is printed by its code and size. */
static void print_rpdo_fault(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	mbx_ev_rpdo_fault e;
	char f[64];

	(void)spec;
	memcpy(&e, m->data, sizeof e);
	ctl_rpdo_fault_text(e.fault, "+", false, f, sizeof f);
	if (m->code == MBX_EV_RPDO_RECOVERED)
		snprintf(out->text, out->len, "RPDO %u (COB-ID %" PRIX32 "h): %s ended (%s)", e.pdo,
			 e.cob_id, f, e.len ? "a correct frame" : "reconfigured");
	else if (e.fault == MBX_RPDO_FAULT_TIMEOUT)
		snprintf(out->text, out->len,
			 "RPDO %u (COB-ID %" PRIX32 "h): %s, %u ms; EMCY %04X sent", e.pdo,
			 e.cob_id, f, e.event_ms, e.emcy);
	else
		snprintf(out->text, out->len,
			 "RPDO %u (COB-ID %" PRIX32 "h): %s, %u bytes, %u mapped; EMCY %04X sent",
			 e.pdo, e.cob_id, f, e.len, e.mapped_len, e.emcy);
	if (!out->o)
		return;
	cJSON_AddNumberToObject(out->o, "ts_us", (double)e.ts_us);
	cJSON_AddNumberToObject(out->o, "pdo", e.pdo);
	cJSON_AddNumberToObject(out->o, "cob_id", e.cob_id);
	cJSON_AddStringToObject(out->o, "fault", f);
	cJSON_AddNumberToObject(out->o, "len", e.len);
	cJSON_AddNumberToObject(out->o, "mapped_len", e.mapped_len);
	cJSON_AddNumberToObject(out->o, "event_ms", e.event_ms);
	if (m->code == MBX_EV_RPDO_FAULT)
		cJSON_AddNumberToObject(out->o, "emcy", e.emcy);
}

static void print_sync(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	mbx_ev_sync e;

	(void)spec;
	memcpy(&e, m->data, sizeof e);
	snprintf(out->text, out->len, "SYNC %s, counter %u", e.produced ? "sent" : "received",
		 e.counter);
	if (!out->o)
		return;
	cJSON_AddNumberToObject(out->o, "ts_us", (double)e.ts_us);
	cJSON_AddNumberToObject(out->o, "counter", e.counter);
	cJSON_AddBoolToObject(out->o, "produced", e.produced);
}

static void print_time(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	mbx_ev_time e;
	char utc[48];
	struct tm tm;

	(void)spec;
	memcpy(&e, m->data, sizeof e);
	time_t s = (time_t)(e.unix_ms / 1000);
	gmtime_r(&s, &tm);
	size_t n = strftime(utc, sizeof utc, "%Y-%m-%dT%H:%M:%S", &tm);
	snprintf(utc + n, sizeof utc - n, ".%03dZ", (int)(e.unix_ms % 1000));
	snprintf(out->text, out->len, "TIME %s %s (day %u, %" PRIu32 " ms)",
		 e.produced ? "sent" : "received", utc, e.days, e.ms);
	if (!out->o)
		return;
	cJSON_AddNumberToObject(out->o, "ts_us", (double)e.ts_us);
	cJSON_AddNumberToObject(out->o, "days", e.days);
	cJSON_AddNumberToObject(out->o, "ms", e.ms);
	cJSON_AddNumberToObject(out->o, "unix_ms", (double)e.unix_ms);
	cJSON_AddStringToObject(out->o, "utc", utc);
	cJSON_AddBoolToObject(out->o, "produced", e.produced);
}

/* A watched device object's typed value (docs/devices.md). */
static void print_dev_value(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	mbx_dev_value v;
	const uint8_t *data;
	const ctl_type *t;
	char *text;

	(void)spec;
	if (cogw_dev_value_parse(m->data, m->len, &v, &data) < 0)
		return (void)snprintf(out->text, out->len, "malformed device value");
	t = cogw_type_of(v.type);
	text = t ? ctl_value_text(t, data, v.len) : ctl_hex_text(data, v.len, 8);
	snprintf(out->text, out->len, "node %u %04X:%02X %s = %s (seq %" PRIu32 ")", v.node,
		 v.index, v.sub, t ? t->cia_name : "?", text ? text : "?", v.seq);
	free(text);
	if (!out->o)
		return;
	cJSON_AddNumberToObject(out->o, "node", v.node);
	cJSON_AddNumberToObject(out->o, "index", v.index);
	cJSON_AddNumberToObject(out->o, "sub", v.sub);
	cJSON_AddNumberToObject(out->o, "seq", v.seq);
	cJSON_AddNumberToObject(out->o, "rx_time_us", (double)v.time_us);
	cJSON_AddNumberToObject(out->o, "bits", v.bits);
	if (t)
		cJSON_AddStringToObject(out->o, "data_type", t->cia_name);
	ctl_value_json(out->o, t, data, v.len);
}

static void print_dev_mirror(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	static const char *const status[] = { "off", "waiting", "full", "partial", "none" };
	static const char *const reason[] = { "", "no free PDO", "COB-ID in use", "OD refused",
					      "not kept" };
	mbx_ev_dev_mirror e;

	(void)spec;
	memcpy(&e, m->data, sizeof e);
	const char *st = e.status < 5 ? status[e.status] : "?";
	const char *why = e.reason < 5 ? reason[e.reason] : "?";
	snprintf(out->text, out->len, "node %u mirror %s: %u PDOs mirrored, %u not%s%s", e.node, st,
		 e.mirrored, e.missing, e.missing ? " - " : "", e.missing ? why : "");
	if (!out->o)
		return;
	cJSON_AddNumberToObject(out->o, "node", e.node);
	cJSON_AddStringToObject(out->o, "mirror", st);
	cJSON_AddNumberToObject(out->o, "mirrored", e.mirrored);
	cJSON_AddNumberToObject(out->o, "missing", e.missing);
	if (e.missing)
		cJSON_AddStringToObject(out->o, "reason", why);
	cJSON_AddNumberToObject(out->o, "generation", e.generation);
}

/* The application watchdog's trip, the own node's NMT, host ready
 * (docs/application.md). */
static void print_app(const cogw_msg *m, const ctl_monitor_spec *spec, event_out *out)
{
	char set[160];

	(void)spec;
	if (m->code == MBX_EV_APP_WD_TIMEOUT) {
		mbx_ev_appwd e;
		memcpy(&e, m->data, sizeof e);
		mbx_appwd_reactions_format(e.done, set, sizeof set);
		snprintf(out->text, out->len,
			 "application watchdog: client %u (pid %u%s) missed its %u ms keep-alive, "
			 "%u us late: %s",
			 e.client, e.pid, e.gone ? ", gone" : "", e.interval_ms, e.late_us, set);
	} else if (m->code == MBX_EV_APP_NMT) {
		mbx_appwd_nmt e;
		memcpy(&e, m->data, sizeof e);
		snprintf(out->text, out->len, "own node %u: %s%s (%u holder%s)", e.node,
			 co_nmt_state_to_string(e.state),
			 e.flags & MBX_APPWD_NMT_REFUSED ? ", start refused and deferred" : "",
			 e.holders, e.holders == 1 ? "" : "s");
	} else {
		mbx_ev_host e;
		memcpy(&e, m->data, sizeof e);
		mbx_appwd_reactions_format(e.done, set, sizeof set);
		snprintf(out->text, out->len, "host %s (client %u)%s%s",
			 e.ready ? "ready" : "NOT READY", e.client, e.ready ? "" : ": ",
			 e.ready ? "" : set);
	}
	if (out->o)
		cJSON_AddStringToObject(out->o, "text", out->text);
}

static const struct {
	uint16_t code;
	event_printer print;
} event_printers[] = {
	{ MBX_EV_DEV_VALUE, print_dev_value },
	{ MBX_EV_DEV_MIRROR, print_dev_mirror },
	{ MBX_EV_NMT_STATE, print_node_event },
	{ MBX_EV_BOOTUP, print_node_event },
	{ MBX_EV_HB_STARTED, print_node_event },
	{ MBX_EV_HB_LOST, print_node_event },
	{ MBX_EV_DUP_NODE, print_dup_node },
	{ MBX_EV_GW_SDO, print_gw_sdo },
	{ MBX_EV_GW_EMCY, print_gw_emcy },
	{ MBX_EV_EMCY, print_emcy },
	{ MBX_EV_PDO, print_pdo },
	{ MBX_EV_SDO_DONE, print_sdo_done },
	{ MBX_EV_MGR_STATE, print_mgr_state },
	{ MBX_EV_MGR_BOOT, print_mgr_boot },
	{ MBX_EV_MGR_NODE, print_mgr_node },
	{ MBX_EV_CAN_STATE, print_can_state },
	{ MBX_EV_COMM_FAULT, print_comm_fault },
	{ MBX_EV_UNKNOWN_NODE, print_unknown_node },
	{ MBX_EV_RAW, print_raw },
	{ MBX_EV_OD_WRITTEN, print_od_written },
	{ MBX_EV_RPDO_FAULT, print_rpdo_fault },
	{ MBX_EV_RPDO_RECOVERED, print_rpdo_fault },
	{ MBX_EV_SYNC, print_sync },
	{ MBX_EV_TIME, print_time },
	{ MBX_EV_GUARD_TOGGLE, print_node_event },
	{ MBX_EV_LIFE_LOST, print_node_event },
	{ MBX_EV_LIFE_RESUMED, print_node_event },
	{ MBX_EV_OVERFLOW, print_overflow },
	{ MBX_EV_APP_WD_TIMEOUT, print_app },
	{ MBX_EV_APP_NMT, print_app },
	{ MBX_EV_HOST_STATE, print_app },
};

static event_printer printer_of(uint16_t code)
{
	for (size_t i = 0; i < sizeof event_printers / sizeof event_printers[0]; i++)
		if (event_printers[i].code == code)
			return event_printers[i].print;
	return NULL;
}

/* The members every event's JSON object starts with. */
static cJSON *event_json_head(const cogw_msg *m, const char *cls, double epoch)
{
	cJSON *o = cJSON_CreateObject();

	if (!o)
		return NULL;
	cJSON_AddNumberToObject(o, "time", epoch);
	cJSON_AddNumberToObject(o, "line", m->line);
	cJSON_AddStringToObject(o, "class", m->code == MBX_EV_OVERFLOW ? "overflow" : cls);
	cJSON_AddStringToObject(o, "event", mbx_event_to_string(m->code));
	if (m->dropped)
		cJSON_AddNumberToObject(o, "dropped_before", m->dropped);
	return o;
}

void ctl_monitor_print(ctl *c, const cogw_msg *m, const ctl_monitor_spec *spec)
{
	char ts[32], text[1024] = "";
	double epoch;
	ctl_timestamp(ts, sizeof ts, &epoch);
	const char *cls = mbx_event_class_to_string(mbx_event_class_of(m->code));
	event_out out = { text, sizeof text, c->json ? event_json_head(m, cls, epoch) : NULL };
	event_printer print = printer_of(m->code);

	if (print)
		print(m, spec, &out);
	else
		snprintf(text, sizeof text, "event 0x%04X (%zu bytes)", m->code, m->len);
	if (out.o) {
		ctl_json_print(out.o);
		return;
	}
	printf("%s line %u %-5s %s", ts, m->line, m->code == MBX_EV_OVERFLOW ? "!" : cls, text);
	if (m->dropped)
		printf(" (%" PRIu32 " earlier events lost)", m->dropped);
	printf("\n");
	fflush(stdout);
}

int ctl_monitor_run(ctl *c, const ctl_monitor_spec *spec)
{
	int ex = 0;
	uint64_t lines = spec->lines;
	if (!lines) {
		int n = ctl_count_lines(c);
		if (n < 0)
			return -n;
		lines = n >= 64 ? UINT64_MAX : (((uint64_t)1 << n) - 1);
	}
	cogw *h = ctl_handle(c, &ex);
	if (!h)
		return ex;
	for (unsigned line = 0; line < MBX_LINES_MAX; line++) {
		if (!(lines & ((uint64_t)1 << line)))
			continue;
		char ctx[64];
		snprintf(ctx, sizeof ctx, "subscribe on line %u", line);
		int rc = cogw_subscribe(h, line, spec->classes,
					spec->n_filters ? spec->filters : NULL, spec->n_filters,
					c->timeout_ms);
		if (rc < 0)
			return ctl_fail(c, rc, 0, ctx);
	}
	/* Say when the subscriptions are in place (stderr: stdout stays pure
	 * events): a person knows it is listening, a script can wait for it. */
	char what[256] = "";
	size_t off = 0;
	for (uint32_t bit = 1; bit && bit <= MBX_EVC_ALL; bit <<= 1)
		if ((spec->classes & bit) && off < sizeof what)
			off += (size_t)snprintf(what + off, sizeof what - off, "%s%s",
						off ? "," : "", mbx_event_class_to_string(bit));
	fprintf(stderr, "cogwctl %s: watching %s events on line%s", c->what, what,
		(lines & (lines - 1)) ? "s" : "");
	for (unsigned line = 0; line < MBX_LINES_MAX; line++)
		if (lines & ((uint64_t)1 << line))
			fprintf(stderr, " %u", line);
	fprintf(stderr, "%s\n", spec->n_filters ? " (raw frames filtered)" : "");

	struct sigaction sa = { .sa_handler = on_signal }; /* no SA_RESTART */
	sigemptyset(&sa.sa_mask);
	sigaction(SIGINT, &sa, NULL);
	sigaction(SIGTERM, &sa, NULL);

	double start = mono_s();
	uint64_t seen = 0;
	while (!interrupted) {
		if (spec->count && seen >= spec->count)
			break;
		double left = spec->duration_s ? spec->duration_s - (mono_s() - start) : 0.2;
		if (left <= 0)
			break;
		int wait_ms = left > 0.2 ? 200 : (int)(left * 1000) + 1;
		cogw_msg m;
		int rc = cogw_recv(h, &m, wait_ms);
		if (rc == COGW_E_AGAIN)
			continue;
		if (rc < 0)
			return ctl_fail(c, rc, 0, "receiving events");
		if (m.kind == MBX_KIND_EVENT && m.line < MBX_LINES_MAX &&
		    (lines & ((uint64_t)1 << m.line))) {
			ctl_monitor_print(c, &m, spec);
			if (m.code != MBX_EV_OVERFLOW)
				seen++;
		}
		cogw_msg_release(&m);
	}
	if (!c->json)
		fprintf(stderr, "cogwctl %s: %" PRIu64 " event%s in %.1f s\n", c->what, seen,
			seen == 1 ? "" : "s", mono_s() - start);
	return 0;
}

/* ---- option helpers ------------------------------------------------------ */

static const struct {
	const char *name;
	uint32_t bits;
} class_names[] = {
	{ "nmt", MBX_EVC_NMT },         { "hb", MBX_EVC_HB },      { "boot", MBX_EVC_BOOT },
	{ "emcy", MBX_EVC_EMCY },       { "pdo", MBX_EVC_PDO },    { "sdo", MBX_EVC_SDO },
	{ "can", MBX_EVC_CAN },         { "raw", MBX_EVC_RAW },    { "od", MBX_EVC_OD },
	{ "manager", MBX_EVC_MANAGER }, { "gateway", MBX_EVC_GW }, { "all", MBX_EVC_ALL },
};

/* Split "a,b,c" and call fn on each part. */
static int each_item(ctl *c, const char *list, int (*fn)(ctl *, const char *, void *), void *arg)
{
	char *copy = strdup(list), *save = NULL;
	int rc = 0;
	for (char *tok = strtok_r(copy, ",", &save); tok && !rc; tok = strtok_r(NULL, ",", &save))
		rc = fn(c, tok, arg);
	if (!rc && (!*list || list[strlen(list) - 1] == ','))
		rc = ctl_usage_error(c, "empty item in list '%s'", list);
	free(copy);
	return rc;
}

static int add_line(ctl *c, const char *s, void *arg)
{
	unsigned line;
	if (ctl_arg_line(c, s, &line) < 0)
		return CTL_EXIT_USAGE;
	*(uint64_t *)arg |= (uint64_t)1 << line;
	return 0;
}

static int add_class(ctl *c, const char *s, void *arg)
{
	for (size_t i = 0; i < sizeof class_names / sizeof class_names[0]; i++)
		if (strcmp(s, class_names[i].name) == 0) {
			*(uint32_t *)arg |= class_names[i].bits;
			return 0;
		}
	/* the other classes by the mailbox's own names (sync, time, pdo-fault) */
	for (uint32_t bit = 1; bit; bit <<= 1)
		if ((bit & MBX_EVC_ALL) && strcmp(s, mbx_event_class_to_string(bit)) == 0) {
			*(uint32_t *)arg |= bit;
			return 0;
		}
	return ctl_usage_error(c,
			       "unknown event class '%s' (nmt, hb, boot, emcy, pdo, sdo, can, raw, "
			       "od, manager, gateway, pdo-fault, sync, time, app, all)",
			       s);
}

static int add_filter(ctl *c, const char *s, void *arg)
{
	ctl_monitor_spec *spec = arg;
	if (spec->n_filters >= MBX_RAW_FILTERS_MAX)
		return ctl_usage_error(c, "at most %u raw filters", MBX_RAW_FILTERS_MAX);
	if (ctl_parse_raw_filter(c, s, &spec->filters[spec->n_filters]) < 0)
		return CTL_EXIT_USAGE;
	spec->n_filters++;
	return 0;
}

static int parse_limits(ctl *c, ctl_monitor_spec *spec, const char *count, const char *duration)
{
	if (count && ctl_arg_uint(c, count, "--count", UINT32_MAX, &spec->count) < 0)
		return CTL_EXIT_USAGE;
	if (count && spec->count == 0)
		return ctl_usage_error(c, "--count must be at least 1");
	if (duration) {
		char *end;
		double d = strtod(duration, &end);
		if (end == duration || *end || !(d > 0) || d > 1e7)
			return ctl_usage_error(c, "--duration '%s': seconds > 0 (e.g. 5 or 0.5)",
					       duration);
		spec->duration_s = d;
	}
	return 0;
}

static int run_monitor(ctl *c, int argc, char **argv)
{
	const char *pos[1];
	int n_pos;
	const char *line = NULL, *cls = NULL, *filter = NULL, *count = NULL, *duration = NULL;
	bool as_float = false;
	ctl_opt opts[] = {
		{ "--line", true, &line, NULL },
		{ "--class", true, &cls, NULL },
		{ "--raw-filter", true, &filter, NULL },
		{ "--count", true, &count, NULL },
		{ "--duration", true, &duration, NULL },
		{ "--float", false, NULL, &as_float },
		{ NULL, false, NULL, NULL },
	};
	int rc = ctl_parse(c, argc, argv, opts, pos, 0, &n_pos);
	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(&ctl_cmd_monitor);
	ctl_monitor_spec spec;
	memset(&spec, 0, sizeof spec);
	spec.as_float = as_float;
	if (line && (rc = each_item(c, line, add_line, &spec.lines)))
		return rc;
	if (cls && (rc = each_item(c, cls, add_class, &spec.classes)))
		return rc;
	if (filter && (rc = each_item(c, filter, add_filter, &spec)))
		return rc;
	if (!cls)
		/* raw frames and SYNCs (up to one per ms) only on request */
		spec.classes = MBX_EVC_ALL & ~(MBX_EVC_RAW | MBX_EVC_SYNC);
	if (spec.n_filters)
		spec.classes |= MBX_EVC_RAW;
	if ((rc = parse_limits(c, &spec, count, duration)))
		return rc;
	return ctl_monitor_run(c, &spec);
}

const ctl_cmd ctl_cmd_monitor = {
	.name = "monitor",
	.synopsis = "  monitor [--line L,..] [--class C,..] [--raw-filter ID[/MASK],..]\n"
		    "          [--count N] [--duration S] [--float]\n"
		    "                                           live events, one line each\n",
	.help = "usage: cogwctl monitor [--line L[,L..]] [--class C[,C..]] [--raw-filter "
		"ID[/MASK][,..]]\n"
		"                       [--count N] [--duration S] [--float]\n"
		"\n"
		"Subscribes to events of the daemon and prints one line per event, with the\n"
		"local time it arrived:\n"
		"  12:00:01.250 line 0 hb    node 1 heartbeat started (pre-operational)\n"
		"  12:00:02.004 line 0 pdo   RPDO 1: B000:00 = 12.5\n"
		"Ends on Ctrl-C (SIGINT/SIGTERM), after N events (--count) or S seconds\n"
		"(--duration, fractions allowed); then prints how many events it saw (stderr).\n"
		"\n"
		"  --line L,..      lines to watch (default: every line of the daemon)\n"
		"  --class C,..     event classes (default: all but raw and sync; gateway =\n"
		"                   routed SDO sessions ending and EMCYs forwarded):\n"
		"                   nmt   NMT state changes (from heartbeats and the daemon's "
		"own)\n"
		"                   hb    heartbeat supervision started / lost, guarding\n"
		"                         toggle errors, our node's life guarding\n"
		"                   boot  boot-up messages\n"
		"                   emcy  emergency messages received, with the error code's "
		"meaning\n"
		"                   pdo   RPDOs received by the daemon, with the mapped values\n"
		"                   sdo   SDO transfers of any client finished\n"
		"                   can   CAN controller state (error-passive, bus-off, ...)\n"
		"                   raw   every CAN frame (can-utils notation 181#0000A040)\n"
		"                   od    the daemon's own object dictionary written over SDO\n"
		"                   pdo-fault  the daemon's RPDOs: deadline missed, too short,\n"
		"                         too long (with the EMCY it sent), and when it ends\n"
		"                   sync  every SYNC sent or received, with its counter\n"
		"                   time  every TIME stamp sent or received\n"
		"                   all   all of these (raw and sync included)\n"
		"  --raw-filter F,..  raw frames matching ID[/MASK] only (hex; 1..3 digits = "
		"11-bit,\n"
		"                   8 digits = 29-bit; at most 4); implies --class raw\n"
		"  --count N        stop after N events\n"
		"  --duration S     stop after S seconds\n"
		"  --float          show PDO values of 4 bytes as REAL32 numbers; without it "
		"every\n"
		"                   value is shown as hex bytes plus the unsigned little-endian "
		"number\n"
		"With --json every event is one JSON object per line (4-byte PDO values always\n"
		"carry an \"r32\" member as well as \"hex\").\n"
		"\n"
		"Examples:\n"
		"  cogwctl monitor\n"
		"  cogwctl monitor --line 0 --class pdo --float --duration 5\n"
		"  cogwctl monitor --class hb,emcy,nmt --json\n"
		"  cogwctl monitor --raw-filter 700/780 --count 10\n",
	.run = run_monitor,
};

/* ---- raw ------------------------------------------------------------------- */

/* can-utils frame syntax: ID#DATA, ID#R, ID#Rn; ID 3 hex digits = 11-bit,
 * 8 = 29-bit; DATA 0..8 bytes, '.' separators allowed. */
static int parse_frame(ctl *c, const char *s, mbx_raw_frame *f)
{
	const char *hash = strchr(s, '#');
	memset(f, 0, sizeof *f);
	if (!hash)
		goto bad;
	size_t n = (size_t)(hash - s);
	if (n != 3 && n != 8)
		goto bad;
	for (size_t i = 0; i < n; i++)
		if (!isxdigit((unsigned char)s[i]))
			goto bad;
	char idbuf[9];
	memcpy(idbuf, s, n);
	idbuf[n] = '\0';
	uint32_t id = (uint32_t)strtoul(idbuf, NULL, 16);
	if (n == 3 ? id > 0x7FF : id > 0x1FFFFFFF)
		goto bad;
	f->id = id | (n == 8 ? MBX_RAW_EXT : 0);
	const char *d = hash + 1;
	if (*d == 'R' || *d == 'r') {
		f->id |= MBX_RAW_RTR;
		if (d[1]) {
			if (d[1] < '0' || d[1] > '8' || d[2])
				goto bad;
			f->len = (uint8_t)(d[1] - '0');
		}
		return 0;
	}
	size_t len;
	const char *err;
	if (strchr(d, ' ') || ctl_parse_hex_bytes(d, f->data, 8, &len, &err) < 0 ||
	    (d[0] == '0' && (d[1] == 'x' || d[1] == 'X')))
		goto bad;
	f->len = (uint8_t)len;
	return 0;
bad:
	ctl_usage_error(c,
			"frame '%s': ID#DATA as cansend writes it (123#DEADBEEF, 12345678#11.22, "
			"123#R, 123#R2);"
			" 3 hex digits = 11-bit id, 8 = 29-bit; at most 8 data bytes",
			s);
	return -1;
}

static int run_raw(ctl *c, int argc, char **argv)
{
	const char *pos[MBX_RAW_SEND_MAX + 2];
	int n_pos;
	const char *count = NULL, *duration = NULL;
	ctl_opt opts[] = {
		{ "--count", true, &count, NULL },
		{ "--duration", true, &duration, NULL },
		{ NULL, false, NULL, NULL },
	};
	int rc = ctl_parse(c, argc, argv, opts, pos, MBX_RAW_SEND_MAX + 2, &n_pos);
	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(&ctl_cmd_raw);
	if (n_pos < 2)
		return ctl_usage_error(c,
				       "expected 'send LINE FRAME...' or 'dump LINE [FILTER...]'");
	unsigned line;
	if (!strcmp(pos[0], "dump")) {
		c->what = "raw dump";
		ctl_monitor_spec spec;
		memset(&spec, 0, sizeof spec);
		if (ctl_arg_line(c, pos[1], &line) < 0)
			return CTL_EXIT_USAGE;
		spec.lines = (uint64_t)1 << line;
		spec.classes = MBX_EVC_RAW;
		if (n_pos - 2 > (int)MBX_RAW_FILTERS_MAX)
			return ctl_usage_error(c, "at most %u filters", MBX_RAW_FILTERS_MAX);
		for (int i = 2; i < n_pos; i++)
			if (ctl_parse_raw_filter(c, pos[i], &spec.filters[spec.n_filters++]) < 0)
				return CTL_EXIT_USAGE;
		if ((rc = parse_limits(c, &spec, count, duration)))
			return rc;
		return ctl_monitor_run(c, &spec);
	}
	if (strcmp(pos[0], "send") != 0)
		return ctl_usage_error(c, "unknown action '%s' (send or dump)", pos[0]);
	c->what = "raw send";
	if (count || duration)
		return ctl_usage_error(c, "--count/--duration are for dump");
	if (ctl_arg_line(c, pos[1], &line) < 0)
		return CTL_EXIT_USAGE;
	if (n_pos < 3)
		return ctl_usage_error(c, "expected at least one FRAME");
	mbx_raw_frame frames[MBX_RAW_SEND_MAX];
	size_t n = 0;
	for (int i = 2; i < n_pos; i++)
		if (parse_frame(c, pos[i], &frames[n++]) < 0)
			return CTL_EXIT_USAGE;
	int ex = 0;
	cogw *h = ctl_handle(c, &ex);
	if (!h)
		return ex;
	char ctx[64];
	snprintf(ctx, sizeof ctx, "raw send on line %u", line);
	rc = cogw_raw_send(h, line, frames, n, c->timeout_ms);
	if (rc < 0)
		return ctl_fail(c, rc, 0, ctx);
	if (c->json) {
		cJSON *o = cJSON_CreateObject();
		cJSON_AddBoolToObject(o, "ok", true);
		cJSON_AddNumberToObject(o, "line", line);
		cJSON_AddNumberToObject(o, "frames", (double)n);
		ctl_json_print(o);
	} else {
		printf("line %u: %zu frame%s sent\n", line, n, n == 1 ? "" : "s");
	}
	return 0;
}

const ctl_cmd ctl_cmd_raw = {
	.name = "raw",
	.synopsis =
		"  raw send LINE ID#DATA...                 send CAN frames through the daemon\n"
		"  raw dump LINE [ID[/MASK]...] [--count N] [--duration S]\n"
		"                                           print CAN frames the line receives\n",
	.help = "usage: cogwctl raw send LINE FRAME...\n"
		"       cogwctl raw dump LINE [ID[/MASK]...] [--count N] [--duration S]\n"
		"\n"
		"send   the daemon puts up to 32 frames on line LINE, in order. FRAME is written "
		"as\n"
		"       for can-utils' cansend: ID#DATA with ID 3 hex digits (11-bit) or 8 hex\n"
		"       digits (29-bit) and DATA 0..8 bytes in hex ('.' separators allowed);\n"
		"       ID#R is a remote frame (ID#R2: with DLC 2).\n"
		"dump   prints the frames the daemon receives on line LINE (the monitor's raw "
		"class),\n"
		"       optionally only those matching up to 4 filters ID[/MASK] (hex; 1..3 digits "
		"=\n"
		"       11-bit, 8 digits = 29-bit; no MASK = exactly that id). Ends on Ctrl-C, "
		"--count\n"
		"       or --duration. Frames the daemon sends itself are not received by it.\n"
		"\n"
		"Examples:\n"
		"  cogwctl raw send 0 601#4018100100000000\n"
		"  cogwctl raw send 2 18FF0001#0102030405060708 701#R\n"
		"  cogwctl raw dump 0 181 700/780 --duration 10\n",
	.run = run_raw,
};
