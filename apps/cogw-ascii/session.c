/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-ascii/session.c - what a CiA 309-3 command does: the
 * connection's defaults, its rights, the mailbox request it becomes and
 * the answer line the daemon's reply turns into (docs/ascii.md).
 *
 * A command's life, in the order of this file:
 *  1. session_line: parse; local commands (set, info, help, events) are
 *     answered at once;
 *  2. resolve net/node with the connection's defaults; check its rights
 *     (a read-only peer gets ERROR: 100 for anything that writes);
 *  3. build the mailbox request (SDO on the network's own line, routed
 *     SDO through route_line for networks not attached, NMT, LSS);
 *  4. launch: at most the daemon's max_outstanding per line are under way
 *     (more would be refused BUSY by the daemon), the rest wait in FIFO
 *     order;
 *  5. session_mailbox: the reply becomes the answer; answers leave in the
 *     order the commands came (flush_answers, into the connection's
 *     output: output.c).
 */
#include "apps/cogw-ascii/gateway.h"

#include "apps/common/mbx_loop.h"

#include <errno.h>
#include <inttypes.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/manager.h"
#include "core/nmt.h"
#include "core/sdo.h"

/* ---- answers ---------------------------------------------------------------- */

/* "[seq] " + body + CR LF, into r->answer (heap: a domain's text can be
 * megabytes). Every answer ends with CR LF whatever the command's line
 * end: the 309-3 tools (CANopenNode's cocomm) read up to CR LF and would
 * wait forever for an answer ending in LF alone. */
static void answer_text(request *r, const char *body, size_t body_len)
{
	char prefix[16] = "";
	int pn = r->cmd.has_seq ? snprintf(prefix, sizeof prefix, "[%" PRIu32 "] ", r->cmd.seq) : 0;
	size_t n = (size_t)pn + body_len + 2;

	free(r->answer);
	r->answer = malloc(n + 1);
	r->done = true;
	if (!r->answer) {
		r->answer_len = 0;
		return;
	}
	memcpy(r->answer, prefix, (size_t)pn);
	memcpy(r->answer + pn, body, body_len);
	memcpy(r->answer + pn + body_len, "\r\n", 2);
	r->answer[n] = '\0';
	r->answer_len = n;
}

static void answer_fmt(request *r, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

static void answer_fmt(request *r, const char *fmt, ...)
{
	char body[256];
	va_list ap;
	int n;

	va_start(ap, fmt);
	n = vsnprintf(body, sizeof body, fmt, ap);
	va_end(ap);
	answer_text(r, body, n < 0 ? 0 : (size_t)n >= sizeof body ? sizeof body - 1 : (size_t)n);
}

static void answer_error(request *r, int err)
{
	answer_fmt(r, "ERROR: %d", err);
}

static void answer_abort(request *r, uint32_t abort)
{
	answer_fmt(r, "ERROR: 0x%08" PRIX32, abort);
}

/* A mailbox status as a 309-3 error number (docs/ascii.md "Errors"). The
 * line was parsed and found well-formed before it became a request: a
 * refusal of its parameters by the daemon is a request it does not
 * support, never a syntax error. */
static int err_of_status(int status)
{
	switch (status) {
	case COGW_E_ACCESS:
	case COGW_E_UNSUPPORTED:
	case COGW_E_UNKNOWN_CMD:
	case COGW_E_PARAM:
	case COGW_E_INVAL:
		return ASCII_E_UNSUPPORTED;
	case COGW_E_TIMEOUT:
	case COGW_E_NO_ANSWER:
	case COGW_E_NOT_FOUND:
		return ASCII_E_TIMEOUT;
	case COGW_E_BAD_LINE:
		return ASCII_E_NET;
	case COGW_E_TOO_BIG:
	case COGW_E_NO_MEMORY:
	case COGW_E_NOMEM:
	case COGW_E_TRUNCATED:
		return ASCII_E_MEMORY;
	default: /* BUSY, FULL, STATE, SHUTDOWN, NO_DAEMON, RESTARTED, ... */
		return ASCII_E_STATE;
	}
}

/* ---- local commands ------------------------------------------------------------ */

static const char help_general[] =
	"[<seq>] [[<net>] <node>] r[ead] <index> <sub> [<type>]\n"
	"[<seq>] [[<net>] <node>] w[rite] <index> <sub> <type> <value>\n"
	"[<seq>] [[<net>] <node>|all] start|stop|preop[erational]|reset node|reset "
	"comm[unication]\n"
	"[<seq>] [<net>] set network|node|sdo_timeout|sdo_block <value>\n"
	"[<seq>] [<net>] lss_... (help lss)\n"
	"[<seq>] [<net>] events on|off [emcy|boot|hb|nmt|manager|all]...\n"
	"[<seq>] info version | help [datatype|lss]\n"
	"answers: [<seq>] OK | [<seq>] <value> | [<seq>] ERROR: <code>\n";
static const char help_datatype[] =
	"b i8 i16 i32 i64 u8 u16 u32 u64 r32 r64: numbers (decimal, or 0x hex in)\n"
	"t td: <days> <ms>; vs: \"text\" (\"\" for a quote)\n"
	"os us d: base64 (RFC 2045); x8 x16 x32 x64 hex: non-standard hex forms\n";
static const char help_lss[] =
	"[<net>] lss_switch_glob 0|1 | lss_switch_sel <vendor> <product> <rev> <serial>\n"
	"[<net>] lss_set_node <node> | lss_conf_bitrate <table> <index>\n"
	"[<net>] lss_activate_bitrate <delay_ms> | lss_store | lss_get_node\n"
	"[<net>] lss_inquire_addr [0..3] | _lss_fastscan [<ms>] | lss_ident_nonconf\n";

/* Help lines, then the command's answer "[seq] OK". */
static void answer_help(request *r)
{
	const char *text = r->cmd.help_topic == 1   ? help_datatype
			   : r->cmd.help_topic == 2 ? help_lss
						    : help_general;
	size_t lines = 0, n = strlen(text);

	for (size_t i = 0; i < n; i++)
		lines += text[i] == '\n';
	char *buf = malloc(n + lines + 32);

	if (!buf) {
		answer_error(r, ASCII_E_MEMORY);
		return;
	}
	size_t k = 0;

	for (size_t i = 0; i < n; i++) {
		if (text[i] == '\n')
			buf[k++] = '\r';
		buf[k++] = text[i];
	}
	answer_fmt(r, "OK");
	char *both = malloc(k + r->answer_len + 1);

	if (!both) {
		free(buf);
		return;
	}
	memcpy(both, buf, k);
	memcpy(both + k, r->answer, r->answer_len + 1);
	free(buf);
	free(r->answer);
	r->answer = both;
	r->answer_len += k;
}

/* The daemon's events of every line, once a connection asks for them.
 * SUBSCRIBE is answered by the mailbox server itself and so has no
 * asynchronous form: this is one short blocking exchange per line, bounded
 * by a second, the first time only. */
static void ensure_subscribed(gateway *g)
{
	static const uint32_t classes = MBX_EVC_NMT | MBX_EVC_HB | MBX_EVC_BOOT | MBX_EVC_EMCY |
					MBX_EVC_MANAGER;

	for (size_t l = 0; l < g->daemon.n_lines; l++) {
		if (g->subscribed[l] == classes)
			continue;
		int rc = cogw_subscribe(g->h, (unsigned)l, classes, NULL, 0, 1000);

		if (rc == 0)
			g->subscribed[l] = classes;
		else if (g->verbose)
			fprintf(stderr, "cogw-ascii: events of line %zu: %s\n", l,
				cogw_strerror(rc));
	}
}

/* set, info, help, events: answered by the gateway itself. */
static bool run_local(gateway *g, conn *c, request *r)
{
	const ascii_cmd *cmd = &r->cmd;

	switch (cmd->verb) {
	case ASCII_V_SET_NETWORK:
		c->net = (int)cmd->args[0];
		break;
	case ASCII_V_SET_NODE:
		c->node = (int)cmd->args[0];
		break;
	case ASCII_V_SET_SDO_TIMEOUT:
		if (cmd->args[0] > g->daemon.mailbox.max_request_timeout_ms) {
			answer_error(r, ASCII_E_SYNTAX);
			return true;
		}
		c->sdo_timeout_ms = cmd->args[0];
		break;
	case ASCII_V_SET_SDO_BLOCK:
		c->sdo_block = cmd->args[0] != 0;
		break;
	case ASCII_V_INFO_VERSION:
		answer_fmt(r, "%s", GW_VERSION);
		return true;
	case ASCII_V_HELP:
		answer_help(r);
		return true;
	case ASCII_V_EVENTS:
		if (cmd->events_on) {
			c->events |= cmd->events;
			ensure_subscribed(g);
		} else {
			c->events &= ~cmd->events;
		}
		break;
	default:
		return false;
	}
	answer_fmt(r, "OK");
	return true;
}

/* ---- mailbox requests ------------------------------------------------------------ */

int session_line_of_net(const gateway *g, unsigned net)
{
	for (size_t l = 0; l < g->daemon.n_lines; l++)
		if (g->daemon.lines[l].network_id == net)
			return (int)l;
	return -1;
}

static int set_payload(request *r, const void *fixed, size_t fixed_len, const uint8_t *data,
		       size_t data_len)
{
	r->payload = malloc(fixed_len + data_len + 1);
	if (!r->payload)
		return ASCII_E_MEMORY;
	memcpy(r->payload, fixed, fixed_len);
	if (data_len)
		memcpy(r->payload + fixed_len, data, data_len);
	r->payload_len = fixed_len + data_len;
	return ASCII_OK;
}

/* CiA 309-3 "set sdo_block": 1 lets transfers of the variable-size types
 * (and downloads of more than 4 bytes) use block transfer; 0 never does
 * (normal upload, expedited or segmented download). */
static uint8_t transfer_mode(const conn *c, const request *r, bool upload, size_t len)
{
	bool variable = !r->cmd.type || r->cmd.type->size == 0;

	if (!c->sdo_block)
		return upload ? SDO_MODE_SEGMENTED : SDO_MODE_EXPEDITED;
	if (upload)
		return variable ? SDO_MODE_BLOCK : SDO_MODE_SEGMENTED;
	return len <= 4 ? SDO_MODE_EXPEDITED : SDO_MODE_BLOCK;
}

static int build_sdo(gateway *g, conn *c, request *r, const uint8_t *data)
{
	bool upload = r->cmd.verb == ASCII_V_READ;
	int line = session_line_of_net(g, r->net);
	mbx_sdo_req s = { .node = r->node,
			  .mode = transfer_mode(c, r, upload, r->cmd.data_len),
			  .index = r->cmd.index,
			  .sub = r->cmd.sub,
			  .timeout_ms = c->sdo_timeout_ms };

	if (r->node < 1)
		return ASCII_E_NODE;
	/* an upload of a variable-size type, or a download that does not fit
	 * one mailbox message, travels in chunks */
	r->large = upload ? (!r->cmd.type || r->cmd.type->size == 0)
			  : r->cmd.data_len + sizeof(mbx_gw_sdo_req) + MBX_HDR_SIZE > MBX_MSG_MIN;
	if (line >= 0) {
		r->line = (unsigned)line;
		r->mbx_cmd = upload ? MBX_CMD_SDO_UPLOAD : MBX_CMD_SDO_DOWNLOAD;
		return set_payload(r, &s, sizeof s, data, upload ? 0 : r->cmd.data_len);
	}
	/* not attached: the routed SDO of the daemon's gateway (docs/gateway.md) */
	mbx_gw_sdo_req gs = { .net = r->net, .sdo = s };

	r->line = g->cfg.route_line;
	r->mbx_cmd = upload ? MBX_CMD_GW_SDO_UPLOAD : MBX_CMD_GW_SDO_DOWNLOAD;
	return set_payload(r, &gs, sizeof gs, data, upload ? 0 : r->cmd.data_len);
}

static int build_nmt(gateway *g, request *r)
{
	static const uint8_t cs[] = {
		[ASCII_V_NMT_START] = CO_NMT_CS_START,
		[ASCII_V_NMT_STOP] = CO_NMT_CS_STOP,
		[ASCII_V_NMT_PREOP] = CO_NMT_CS_ENTER_PREOP,
		[ASCII_V_NMT_RESET_NODE] = CO_NMT_CS_RESET_NODE,
		[ASCII_V_NMT_RESET_COMM] = CO_NMT_CS_RESET_COMM,
	};
	int line = session_line_of_net(g, r->net);
	mbx_nmt_req n = { .cs = cs[r->cmd.verb], .node = r->node };

	if (line < 0)
		return ASCII_E_NET; /* the mailbox sends NMT on the daemon's own lines only */
	r->line = (unsigned)line;
	r->mbx_cmd = MBX_CMD_NMT;
	return set_payload(r, &n, sizeof n, NULL, 0);
}

static int build_lss(gateway *g, request *r)
{
	const uint32_t *a = r->cmd.args;
	int line = session_line_of_net(g, r->net);
	mbx_lss_req q = { 0 };

	if (line < 0)
		return ASCII_E_NET;
	r->line = (unsigned)line;
	switch (r->cmd.verb) {
	case ASCII_V_LSS_SWITCH_GLOB:
		r->mbx_cmd = MBX_CMD_LSS_SWITCH_GLOBAL;
		q.mode = (uint8_t)a[0];
		break;
	case ASCII_V_LSS_SWITCH_SEL:
		r->mbx_cmd = MBX_CMD_LSS_SWITCH_SELECTIVE;
		q.vendor = a[0];
		q.product = a[1];
		q.rev_lo = a[2];
		q.ser_lo = a[3];
		break;
	case ASCII_V_LSS_SET_NODE:
		r->mbx_cmd = MBX_CMD_LSS_SET_NODE_ID;
		q.node = (uint8_t)a[0];
		if (q.node == 0 || (q.node > 127 && q.node != 255))
			return ASCII_E_NODE;
		break;
	case ASCII_V_LSS_CONF_BITRATE:
		r->mbx_cmd = MBX_CMD_LSS_SET_BIT_TIMING;
		q.table = (uint8_t)a[0];
		q.bit_index = (uint8_t)a[1];
		break;
	case ASCII_V_LSS_ACTIVATE_BITRATE:
		r->mbx_cmd = MBX_CMD_LSS_ACTIVATE_BIT_TIMING;
		q.delay_ms = (uint16_t)a[0];
		break;
	case ASCII_V_LSS_STORE:
		r->mbx_cmd = MBX_CMD_LSS_STORE;
		break;
	case ASCII_V_LSS_INQUIRE_ADDR:
		/* 0..3: vendor, product, revision, serial (CiA 305 5Ah..5Dh) */
		r->mbx_cmd = MBX_CMD_LSS_INQUIRE;
		q.what = (uint8_t)(0x5A + (r->cmd.n_args ? a[0] : 0));
		break;
	case ASCII_V_LSS_GET_NODE:
		r->mbx_cmd = MBX_CMD_LSS_INQUIRE;
		q.what = 0x5E;
		break;
	case ASCII_V_LSS_FASTSCAN:
		r->mbx_cmd = MBX_CMD_LSS_FASTSCAN;
		q.timeout_ms = r->cmd.n_args ? a[0] : 0;
		break;
	case ASCII_V_LSS_IDENT_NONCONF:
		r->mbx_cmd = MBX_CMD_LSS_IDENTIFY_NONCONF;
		break;
	default:
		return ASCII_E_UNSUPPORTED;
	}
	return set_payload(r, &q, sizeof q, NULL, 0);
}

static void sent_add(gateway *g, request *r)
{
	if (g->n_sent == g->cap_sent) {
		size_t cap = g->cap_sent ? 2 * g->cap_sent : 64;
		request **s = realloc(g->sent, cap * sizeof *s);

		if (!s)
			abort(); /* start-up sized it for every slot; cannot happen */
		g->sent = s;
		g->cap_sent = cap;
	}
	g->sent[g->n_sent++] = r;
}

/* r's mailbox request is over (replied or given up): its slot is free. */
static void slot_free(gateway *g, request *r)
{
	r->in_flight = false;
	if (g->inflight[r->line])
		g->inflight[r->line]--;
	if (g->inflight_total)
		g->inflight_total--;
	if (r->large && g->large_inflight[r->line])
		g->large_inflight[r->line]--;
}

static request *sent_take(gateway *g, uint64_t corr)
{
	for (size_t i = 0; i < g->n_sent; i++) {
		if (g->sent[i]->corr == corr) {
			request *r = g->sent[i];

			g->sent[i] = g->sent[--g->n_sent];
			slot_free(g, r);
			return r;
		}
	}
	return NULL;
}

static void request_free(request *r)
{
	if (!r)
		return;
	free(r->payload);
	free(r->answer);
	free(r);
}

/* A request its connection no longer holds: freed now, or, while the
 * daemon still works on it, when its reply (or its turn) comes. */
static void request_release(gateway *g, request *r)
{
	if (r->in_flight || r->waiting) {
		r->conn = NULL;
		g->st.orphaned++;
		return;
	}
	request_free(r);
}

/* Answers done at the head of c's ring go out in order. */
static void flush_answers(gateway *g, conn *c)
{
	while (c->count) {
		request *r = c->slots[c->head];

		if (!r->done)
			break;
		if (r->answer)
			conn_write(c, r->answer, r->answer_len);
		else
			conn_write(c, "ERROR: 600\r\n", 12);
		c->head = (c->head + 1) % g->cfg.max_outstanding;
		c->count--;
		free(r->answer);
		r->answer = NULL;
		request_release(g, r);
	}
	c->kick = true;
}

static void finished(gateway *g, request *r)
{
	if (!r->conn) {
		request_free(r); /* its connection went meanwhile */
		return;
	}
	flush_answers(g, r->conn);
}

/* The request to the daemon, without waiting: false when the line's
 * command queue has no room now (COGW_E_WOULDBLOCK; the request keeps its
 * place and the line waits, server.c); true when it is under way or
 * answered with an error. */
static bool send_one(gateway *g, request *r)
{
	int rc = mbx_loop_send(g->h, r->line, r->mbx_cmd, r->payload, r->payload_len,
			       g->cfg.request_timeout_ms, &r->corr);

	if (rc == COGW_E_WOULDBLOCK) {
		g->blocked[r->line] = g->blocked[r->line] == GW_ROOM ? GW_AGAIN : GW_BLOCKED;
		return false;
	}
	g->blocked[r->line] = GW_FREE;
	free(r->payload);
	r->payload = NULL;
	if (rc < 0) {
		g->st.mbx_errors++;
		r->corr = 0;
		answer_error(r, err_of_status(rc));
		finished(g, r);
		return true;
	}
	r->in_flight = true;
	g->inflight[r->line]++;
	g->inflight_total++;
	g->large_inflight[r->line] += r->large;
	sent_add(g, r);
	return true;
}

/* Can r go to the daemon now? Not while its line's command queue is full
 * (held: it was refused in this pass; GW_BLOCKED: the loop waits for room),
 * at most max_outstanding per line (more would be refused BUSY), as many in
 * all as the response queue holds answers (libcogw refuses more), and one
 * chunked transfer per line at a time: the daemon keeps up to half of our
 * response queue filled with the chunks of each transfer
 * (docs/mailbox.md), so two at once could fill it and leave no room for
 * the other connections' answers. */
static bool may_launch(const gateway *g, const request *r, const bool *held)
{
	return !held[r->line] && g->blocked[r->line] != GW_BLOCKED &&
	       g->inflight[r->line] < g->inflight_max && g->inflight_total < GW_RESP_DEPTH &&
	       !(r->large && g->large_inflight[r->line]);
}

void session_launch(gateway *g)
{
	request **pp = &g->wait_head, *prev = NULL;
	bool held[COGW_LINES_MAX] = { false }; /* refused: the line's later ones wait too */

	while (*pp) {
		request *r = *pp;

		if (r->conn && !may_launch(g, r, held)) {
			prev = r;
			pp = &r->next_wait;
			continue;
		}
		*pp = r->next_wait;
		r->next_wait = NULL;
		r->waiting = false;
		if (!r->conn) {
			request_free(r);
		} else if (!send_one(g, r)) {
			/* its place again: r is untouched */
			r->next_wait = *pp;
			r->waiting = true;
			*pp = r;
			held[r->line] = true;
			prev = r;
			pp = &r->next_wait;
			continue;
		}
		if (!*pp)
			g->wait_tail = prev;
	}
}

static void enqueue(gateway *g, request *r)
{
	r->next_wait = NULL;
	r->waiting = true;
	if (g->wait_tail)
		g->wait_tail->next_wait = r;
	else
		g->wait_head = r;
	g->wait_tail = r;
	session_launch(g);
}

/* Steps 2-4 for a command that goes to the daemon. */
static int start_remote(gateway *g, conn *c, request *r, const uint8_t *data)
{
	const ascii_cmd *cmd = &r->cmd;
	int net = cmd->net >= 0 ? cmd->net : c->net;
	int node = cmd->node >= 0 ? cmd->node : c->node;
	bool lss = cmd->verb >= ASCII_V_LSS_SWITCH_GLOB && cmd->verb <= ASCII_V_LSS_IDENT_NONCONF;
	int rc;

	if (net < 1)
		return ASCII_E_NO_NET;
	if (!lss && node < 0)
		return ASCII_E_NO_NODE;
	if (ascii_verb_writes(cmd->verb) && c->access < COGW_ACCESS_WRITE) {
		g->st.denied++;
		return ASCII_E_UNSUPPORTED;
	}
	r->net = (uint16_t)net;
	r->node = (uint8_t)(node < 0 ? 0 : node);
	if (cmd->verb == ASCII_V_READ || cmd->verb == ASCII_V_WRITE)
		rc = build_sdo(g, c, r, data);
	else if (lss)
		rc = build_lss(g, r);
	else
		rc = build_nmt(g, r);
	if (rc)
		return rc;
	enqueue(g, r);
	return ASCII_OK;
}

void session_line(gateway *g, conn *c, const char *line, size_t len)
{
	size_t cap = len + 8;
	uint8_t *data;
	request *r;
	int rc;

	if (cap > g->daemon.mailbox.max_transfer + 8u)
		cap = g->daemon.mailbox.max_transfer + 8u;
	data = malloc(cap);
	r = calloc(1, sizeof *r);
	if (!r || !data) {
		free(r);
		free(data);
		conn_write(c, "ERROR: 600\r\n", 12);
		return;
	}
	r->conn = c;
	rc = ascii_parse(line, len, &r->cmd, data, cap);
	if (rc == ASCII_OK && r->cmd.verb == ASCII_V_NONE) {
		/* an empty line or a comment: an empty line in its turn, as the
		 * 309-3 tools wait for an answer to every line they send */
		free(data);
		c->slots[(c->head + c->count) % g->cfg.max_outstanding] = r;
		c->count++;
		answer_text(r, "", 0);
		flush_answers(g, c);
		return;
	}
	if (r->cmd.verb == ASCII_V_WRITE && r->cmd.data_len > g->daemon.mailbox.max_transfer)
		rc = ASCII_E_MEMORY;
	g->st.commands++;
	c->slots[(c->head + c->count) % g->cfg.max_outstanding] = r;
	c->count++;
	if (rc) {
		g->st.syntax_errors += rc == ASCII_E_SYNTAX;
		answer_error(r, rc);
	} else if (!run_local(g, c, r)) {
		rc = start_remote(g, c, r, data);
		if (rc)
			answer_error(r, rc);
	}
	free(data);
	flush_answers(g, c);
}

void session_refuse(gateway *g, conn *c, int err)
{
	request *r;

	if (c->count >= g->cfg.max_outstanding || !(r = calloc(1, sizeof *r)))
		return;
	r->conn = c;
	r->cmd.net = r->cmd.node = -1;
	c->slots[(c->head + c->count) % g->cfg.max_outstanding] = r;
	c->count++;
	answer_error(r, err);
	flush_answers(g, c);
}

/* ---- replies ---------------------------------------------------------------------- */

static int lss_error(const request *r, const mbx_lss_resp *q)
{
	if (!q)
		return ASCII_E_LSS_VENDOR;
	if (q->error == 255)
		return ASCII_E_LSS_VENDOR;
	switch (r->cmd.verb) {
	case ASCII_V_LSS_SET_NODE:
		return ASCII_E_LSS_NODE;
	case ASCII_V_LSS_CONF_BITRATE:
		return ASCII_E_LSS_BITRATE;
	case ASCII_V_LSS_STORE:
		return q->error == 1 ? ASCII_E_UNSUPPORTED : ASCII_E_LSS_STORE;
	default:
		return ASCII_E_LSS_VENDOR;
	}
}

static void answer_read(request *r, const uint8_t *data, size_t len)
{
	static const ascii_type hex = { "hex", ASCII_K_HEXBYTES, 0, false };
	const ascii_type *t = r->cmd.type ? r->cmd.type : &hex;
	size_t cap = ascii_value_text_max(t, len);
	char *text = malloc(cap);
	long n;

	if (!text) {
		answer_error(r, ASCII_E_MEMORY);
		return;
	}
	n = ascii_value_format(t, data, len, text, cap);
	if (n == -EBADMSG)
		answer_abort(r, 0x06070010u); /* the device's value has another size */
	else if (n < 0)
		answer_error(r, ASCII_E_MEMORY);
	else
		answer_text(r, text, (size_t)n);
	free(text);
}

static void answer_reply(request *r, const cogw_msg *m)
{
	const mbx_lss_resp *q = m->len >= sizeof(mbx_lss_resp) ? (const void *)m->data : NULL;

	if (m->status == COGW_E_ABORT) {
		answer_abort(r, m->abort);
		return;
	}
	if (m->status == COGW_E_NOT_FOUND && r->cmd.verb == ASCII_V_LSS_IDENT_NONCONF) {
		answer_fmt(r, "0"); /* nobody non-configured answered */
		return;
	}
	if (m->status == COGW_E_LSS) {
		answer_error(r, lss_error(r, q));
		return;
	}
	if (m->status < 0) {
		answer_error(r, err_of_status(m->status));
		return;
	}
	switch (r->cmd.verb) {
	case ASCII_V_READ:
		answer_read(r, m->data, m->len);
		return;
	case ASCII_V_LSS_INQUIRE_ADDR:
	case ASCII_V_LSS_GET_NODE:
		if (!q)
			break;
		if (r->cmd.verb == ASCII_V_LSS_GET_NODE)
			answer_fmt(r, "%" PRIu32, q->value);
		else
			answer_fmt(r, "0x%08" PRIX32, q->value);
		return;
	case ASCII_V_LSS_FASTSCAN:
		if (!q)
			break;
		if (!q->found)
			answer_error(r, ASCII_E_TIMEOUT);
		else
			answer_fmt(r,
				   "0x%08" PRIX32 " 0x%08" PRIX32 " 0x%08" PRIX32 " 0x%08" PRIX32,
				   q->id[0], q->id[1], q->id[2], q->id[3]);
		return;
	case ASCII_V_LSS_IDENT_NONCONF:
		if (!q)
			break;
		answer_fmt(r, "%u", q->found ? 1u : 0u);
		return;
	default:
		answer_fmt(r, "OK");
		return;
	}
	answer_error(r, ASCII_E_STATE); /* a reply without its payload */
}

/* ---- events ----------------------------------------------------------------------- */

static const char *nmt_word(uint8_t s)
{
	switch (s) {
	case 0:
		return "INITIALISING";
	case 4:
		return "STOPPED";
	case 5:
		return "OPERATIONAL";
	case 127:
		return "PRE-OPERATIONAL";
	default:
		return "UNKNOWN";
	}
}

/* The unsolicited line of an event, "" if it is none of ours. */
static uint32_t event_text(const gateway *g, const cogw_msg *m, char *buf, size_t cap)
{
	unsigned net = m->line < g->daemon.n_lines ? g->daemon.lines[m->line].network_id : 0;
	const mbx_ev_node *en = (const void *)m->data;

	buf[0] = '\0';
	switch (m->code) {
	case MBX_EV_EMCY: {
		const mbx_ev_emcy *e = (const void *)m->data;

		snprintf(buf, cap, "%u %u EMCY 0x%04X 0x%02X 0x%02X%02X%02X%02X%02X", net, e->node,
			 e->code, e->reg, e->msef[0], e->msef[1], e->msef[2], e->msef[3],
			 e->msef[4]);
		return ASCII_EV_EMCY;
	}
	case MBX_EV_BOOTUP:
		snprintf(buf, cap, "%u %u ERROR: %d", net, en->node, ASCII_E_BOOT_UP);
		return ASCII_EV_BOOT;
	case MBX_EV_HB_STARTED:
		snprintf(buf, cap, "%u %u ERROR: %d", net, en->node, ASCII_E_HB_STARTED);
		return ASCII_EV_HB;
	case MBX_EV_HB_LOST:
		snprintf(buf, cap, "%u %u ERROR: %d", net, en->node, ASCII_E_HB_LOST);
		return ASCII_EV_HB;
	case MBX_EV_NMT_STATE:
		snprintf(buf, cap, "%u %u NMT %s", net, en->node, nmt_word(en->state));
		return ASCII_EV_NMT;
	case MBX_EV_MGR_BOOT: {
		const mbx_ev_mgr *e = (const void *)m->data;

		snprintf(buf, cap, "%u %u BOOT %s %c", net, e->node, co_mgr_step_to_string(e->step),
			 e->status ? e->status : '-');
		return ASCII_EV_MANAGER;
	}
	default:
		return 0;
	}
}

static void deliver_event(gateway *g, const cogw_msg *m)
{
	char text[160];
	uint32_t cls = event_text(g, m, text, sizeof text);

	if (!cls)
		return;
	for (conn *c = g->conns; c; c = c->next) {
		if (!(c->events & cls) || c->dead)
			continue;
		size_t n = strlen(text);
		char line[168];

		memcpy(line, text, n);
		memcpy(line + n, "\r\n", 2);
		conn_write(c, line, n + 2);
	}
}

void session_mailbox(gateway *g, const cogw_msg *m)
{
	request *r;

	if (m->kind == MBX_KIND_EVENT) {
		deliver_event(g, m);
		return;
	}
	r = sent_take(g, m->corr);
	if (!r)
		return; /* a subscription's answer, or a request given up on */
	if (m->status < 0 && m->status != COGW_E_ABORT && g->verbose)
		fprintf(stderr, "cogw-ascii: %s on line %u: %s\n",
			ascii_verb_to_string(r->cmd.verb), r->line, cogw_strerror(m->status));
	if (r->conn && !r->done)
		answer_reply(r, m);
	if (m->status == COGW_E_TIMEOUT)
		g->st.expired++;
	finished(g, r);
	session_launch(g);
}

/* At exit: requests still under way or waiting. */
void session_free_all(gateway *g)
{
	for (size_t i = 0; i < g->n_sent; i++)
		if (!g->sent[i]->conn)
			request_free(g->sent[i]);
	g->n_sent = 0;
	while (g->wait_head) {
		request *r = g->wait_head;

		g->wait_head = r->next_wait;
		if (!r->conn)
			request_free(r);
	}
	g->wait_tail = NULL;
}

void session_conn_gone(gateway *g, conn *c)
{
	for (unsigned i = 0; i < c->count; i++)
		request_release(g, c->slots[(c->head + i) % g->cfg.max_outstanding]);
	c->count = 0;
}
