/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/test_config_docs.c - the defaults docs/config.md promises are
 * the ones the code uses (the document once gave 0 as 1029h's
 * default while the daemon deliberately uses 1).
 *
 * - The key tables (top level, `mailbox`, `lines[]`, `debug`): every row
 *   with a plain default (number, boolean, `string`) is compared with what
 *   the configuration loader fills in for a minimal configuration; a row
 *   with a plain default that this test does not know fails, so a new key
 *   cannot slip by unchecked.
 * - The table of the line's object dictionary: every row whose default
 *   column is a number, "80h + id", or a configuration key (optionally
 *   several, " / "-separated for several objects or subs) is compared with
 *   the OD the loader builds; rows with prose defaults are counted and a
 *   minimum of checked rows is required.
 *
 * Runs from the repository root (make unit does).
 */
#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "unity.h"

#include "apps/common/config.h"
#include "apps/common/node_config.h"
#include "core/od.h"

#include "core/manager.h"
#include "core/nmt.h"
#include "mailbox/proto.h"

#define DOC "docs/config.md"
#define NODE_ID 5
/* A minimal configuration, plus one slave node with a configuration
 * (for the defaults of the node configuration keys). */
#define MIN_CFG                                                                         \
	"{\"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 500000, \"node_id\": 5, " \
	"\"nodes\": [{\"id\": 7, \"config\": {\"entries\": [{\"index\": \"0x1017\", "   \
	"\"type\": \"UNSIGNED16\", \"value\": 500}]}}]}]}"

static cogw_config cfg;
static char err[512];
static char *doc;

void setUp(void)
{
	memset(&cfg, 0, sizeof cfg);
	TEST_ASSERT_EQUAL_INT_MESSAGE(
		0, cogw_config_load_string(&cfg, MIN_CFG, "t.json", err, sizeof err), err);
}

void tearDown(void)
{
	cogw_config_free(&cfg);
}

static char *read_doc(void)
{
	FILE *f = fopen(DOC, "rb");
	static char buf[256 * 1024];
	size_t n;

	TEST_ASSERT_NOT_NULL_MESSAGE(f, "cannot open " DOC " (run from the repository root)");
	n = fread(buf, 1, sizeof buf - 1, f);
	fclose(f);
	buf[n] = '\0';
	return buf;
}

/* Split a table row "| a | b | c |" into trimmed cells (in place). Cells
 * may contain "\|" (escaped bar). Returns the number of cells. */
static int split_row(char *line, char **cells, int max)
{
	int n = 0;
	char *p = line;

	if (*p != '|')
		return 0;
	p++;
	while (*p && n < max) {
		char *start = p, *w = p;
		while (*p && !(*p == '|' && (p == start || p[-1] != '\\')))
			*w++ = *p++;
		if (!*p)
			break;
		*w = '\0';
		p++;
		while (*start == ' ')
			start++;
		for (char *e = start + strlen(start); e > start && e[-1] == ' ';)
			*--e = '\0';
		cells[n++] = start;
	}
	return n;
}

/* ---- key tables ------------------------------------------------------------ */

/* What the loader filled in, as the document would write it. */
struct key_default {
	const char *section; /* heading the table is under */
	const char *key;
	char actual[300];
};

/* PDO communication records from base on (1400h.. / 1800h..). */
static unsigned count_records(const co_od *od, uint16_t base)
{
	unsigned n = 0;
	while (n < 512 && co_od_find(od, (uint16_t)(base + n), 0))
		n++;
	return n;
}

static int fill_key_defaults(struct key_default *k)
{
	const cogw_line_config *l = &cfg.lines[0];
	const cogw_mailbox_config *m = &cfg.mailbox;
	int n = 0;
#define KD(sec, name, fmt, val)                        \
	(k[n] = (struct key_default){ sec, name, "" }, \
	 snprintf(k[n].actual, sizeof k[n].actual, fmt, val), n++)
	KD("Top level", "version", "%d", 1); /* the loader refuses anything else */
	KD("Top level", "state_dir", "%s", cfg.state_dir);
	KD("Top level", "mlockall", "%s", cfg.mlockall ? "true" : "false");
	KD("Top level", "watchdog_check_ms", "%u", cfg.watchdog_check_ms);
	KD("Top level", "file_memory", "%u", cfg.file_memory);
	KD("`mailbox`", "instance", "%s", m->instance);
	KD("`mailbox`", "depth", "%u", m->depth);
	KD("`mailbox`", "msg_size", "%u", m->msg_size);
	KD("`mailbox`", "queue_mode", "%04o", m->queue_mode);
	KD("`mailbox`", "max_clients", "%u", m->max_clients);
	KD("`mailbox`", "lease_ms", "%u", m->lease_ms);
	KD("`mailbox`", "max_transfer", "%u", m->max_transfer);
	KD("`mailbox`", "max_outstanding", "%u", m->max_outstanding);
	KD("`mailbox`", "max_request_timeout_ms", "%u", m->max_request_timeout_ms);
	KD("`mailbox`", "max_read_outstanding", "%u", m->max_read_outstanding);
	KD("`mailbox`", "transfer_slots", "%u", m->transfer_slots);
	KD("`mailbox`", "transfer_stall_ms", "%u", m->transfer_stall_ms);
	KD("`mailbox`", "transfer_lifetime_ms", "%u", m->transfer_lifetime_ms);
	KD("`mailbox`", "transfer_memory", "%u", m->transfer_memory);
	KD("`mailbox`", "default_access", "%s",
	   m->default_access == COGW_ACCESS_WRITE  ? "write"
	   : m->default_access == COGW_ACCESS_READ ? "read"
						   : "none");
	KD("`lines[]`", "name", "%s", "line<N>");
	KD("`lines[]`", "sdo_servers", "%u", l->sdo_servers);
	KD("`lines[]`", "sdo_clients", "%u", l->sdo_clients);
	KD("`lines[]`", "sdo_timeout_ms", "%u", l->sdo_timeout_ms);
	KD("`lines[]`", "sdo_block_threshold", "%u", l->sdo_block_threshold);
	KD("`lines[]`", "heartbeat_ms", "%u", l->heartbeat_ms);
	KD("`lines[]`", "sync_period_us", "%u", l->sync_period_us);
	KD("`lines[]`", "time_period_ms", "%u", l->time_period_ms);
	KD("`lines[]`", "id_conflict_quiet_ms", "%u", l->id_conflict_quiet_ms);
	KD("`lines[]`", "fault_quiet_ms", "%u", l->fault_quiet_ms);
	KD("`lines[]`", "rpdos", "%u", count_records(l->od, 0x1400));
	KD("`lines[]`", "tpdos", "%u", count_records(l->od, 0x1800));
	KD("`lines[]`", "pdo", "%s", l->pdo == 0 ? "off" : "not off");
	KD("`lines[]`", "pdo_scan_max", "%u", l->pdo_scan_max);
	KD("Unknown nodes (`unknown_nodes`)", "policy", "%s",
	   mbx_unknown_policy_to_string(l->unknown.policy));
	KD("Unknown nodes (`unknown_nodes`)", "heartbeat_ms", "%u", l->unknown.heartbeat_ms);
	KD("Unknown nodes (`unknown_nodes`)", "sdo_timeout_ms", "%u", l->unknown.sdo_timeout_ms);
	KD("The application (`app`)", "max_created", "%u", l->app.max_created);
	KD("The application (`app`)", "max_per_client", "%u", l->app.max_per_client);
	KD("The application (`app`)", "indications", "%u", l->app.indications);
	KD("The application (`app`)", "not_ready_nmt", "%s",
	   l->appwd.not_ready_cs == CO_NMT_CS_STOP ? "stop" : "pre-operational");
	TEST_ASSERT_EQUAL_size_t(1, l->n_nodes);
	KD("Node configuration", "store", "%s", l->nodes[0].config.store ? "true" : "false");
	{
		/* the manager's keys: a line with "manager": {} and one node */
		static cogw_config mc;
		static const char *sec = "The manager (`manager` and `nodes`)";
		cogw_config_free(&mc);
		memset(&mc, 0, sizeof mc);
		TEST_ASSERT_EQUAL_INT_MESSAGE(
			0,
			cogw_config_load_string(
				&mc,
				"{\"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 500000, "
				"\"node_id\": 5, \"manager\": {}, \"nodes\": [{\"id\": 7}]}]}",
				"m.json", err, sizeof err),
			err);
		const cogw_manager_config *g = &mc.lines[0].manager;
		const cogw_node *nd = &mc.lines[0].nodes[0];
		uint32_t b = g->nmt_startup, a = nd->assignment;
#define TF(x) ((x) ? "true" : "false")
		KD(sec, "master", "%s", TF(b & CO_MGR_1F80_MASTER));
		KD(sec, "start_all", "%s", TF(b & CO_MGR_1F80_START_ALL));
		KD(sec, "self_start", "%s", TF(!(b & CO_MGR_1F80_NO_SELF_START)));
		KD(sec, "start_slaves", "%s", TF(!(b & CO_MGR_1F80_APP_STARTS_SLAVES)));
		KD(sec, "on_mandatory_error", "%s",
		   b & CO_MGR_1F80_RESET_ALL_ON_ERROR  ? "reset_all"
		   : b & CO_MGR_1F80_STOP_ALL_ON_ERROR ? "stop_all"
						       : "node");
		KD(sec, "boot_time_ms", "%u", g->boot_time_ms);
		KD(sec, "retry_ms", "%u", g->retry_ms);
		KD(sec, "scan_ms", "%u", g->scan_ms);
		KD(sec, "reset_wait_ms", "%u", g->reset_wait_ms);
		KD(sec, "sdo_timeout_ms", "%u", g->sdo_timeout_ms);
		KD(sec, "max_parallel", "%u", g->max_parallel);
		KD(sec, "accept_remote_nmt", "%s", TF(g->accept_remote_nmt));
		KD(sec, "boot", "%s", TF(a & CO_MGR_1F81_BOOT));
		KD(sec, "mandatory", "%s", TF(a & CO_MGR_1F81_MANDATORY));
		KD(sec, "keep_alive", "%s", TF(a & CO_MGR_1F81_KEEP_ALIVE));
		KD(sec, "retry_factor", "%u", CO_MGR_1F81_RETRY_FACTOR(a));
		KD(sec, "guard_time_ms", "%u", CO_MGR_1F81_GUARD_MS(a));
		KD(sec, "heartbeat_ms", "%u", nd->heartbeat_ms);
		KD(sec, "device_type", "%u", nd->identity[0]);
		KD(sec, "vendor_id", "%u", nd->identity[1]);
		KD(sec, "product_code", "%u", nd->identity[2]);
		KD(sec, "revision", "%u", nd->identity[3]);
		KD(sec, "serial", "%u", nd->identity[4]);
		KD(sec, "keep_op", "%s", TF(nd->keep_op));
		KD(sec, "state", "%s",
		   nd->target_state == CO_NMT_STOPPED           ? "stopped"
		   : nd->target_state == CO_NMT_PRE_OPERATIONAL ? "pre-operational"
								: "operational");
		KD(sec, "software_id", "%u", nd->software_id);
		KD(sec, "software_update", "%s", TF(a & CO_MGR_1F81_UPDATE_SW));
#undef TF
	}
	KD("`debug`", "stall_signal", "%s", cfg.debug_stall_signal ? "true" : "false");
	KD("`debug`", "stall_ms", "%u", cfg.debug_stall_ms);
#undef KD
	TEST_ASSERT_EQUAL_STRING("line0", l->name); /* "line<N>" for line 0 */
	return n;
}

/* A plain default: `word`, `"word"`, a number or a boolean. Writes it
 * without quotes/backticks; false for prose, objects, "see below", ... */
static bool plain_default(const char *cell, char *out, size_t len)
{
	char tmp[128];
	size_t n = strlen(cell);

	if (n == 0 || n >= sizeof tmp)
		return false;
	memcpy(tmp, cell, n + 1);
	char *s = tmp;
	if (s[0] == '`' && s[n - 1] == '`' && n >= 2) {
		s[n - 1] = '\0';
		s++;
		n -= 2;
		if (n >= 2 && s[0] == '"' && s[n - 1] == '"') {
			s[n - 1] = '\0';
			s++;
		}
		if (strchr(s, '{') || strchr(s, '[') || strchr(s, ' '))
			return false; /* an object or array literal */
		snprintf(out, len, "%s", s);
		return true;
	}
	if (!strcmp(s, "true") || !strcmp(s, "false")) {
		snprintf(out, len, "%s", s);
		return true;
	}
	for (const char *p = s; *p; p++)
		if (!isdigit((unsigned char)*p))
			return false;
	snprintf(out, len, "%s", s);
	return true;
}

static void test_key_tables_match_the_loader(void)
{
	struct key_default k[96];
	int nk = fill_key_defaults(k);
	bool seen[96] = { false };
	char section[64] = "";
	char msg[512];
	int checked = 0;

	doc = read_doc();
	for (char *line = strtok(doc, "\n"); line; line = strtok(NULL, "\n")) {
		char *cells[8];
		char want[128];
		int nc;

		if (!strncmp(line, "## ", 3)) {
			snprintf(section, sizeof section, "%s", line + 3);
			continue;
		}
		if (!strncmp(line, "### ", 4))
			continue; /* sub-headings stay in their section */
		nc = split_row(line, cells, 8);
		if (nc < 3 || cells[0][0] != '`')
			continue;
		if (!plain_default(cells[2], want, sizeof want))
			continue;
		/* "`a`, `b`": one default for several keys */
		for (char *kp = cells[0]; kp && *kp == '`';) {
			char key[64];
			char *end = strchr(kp + 1, '`');
			TEST_ASSERT_NOT_NULL(end);
			snprintf(key, sizeof key, "%.*s", (int)(end - kp - 1), kp + 1);
			kp = !strncmp(end + 1, ", `", 3) ? end + 3 : NULL;
			int i;
			for (i = 0; i < nk; i++)
				if (!strcmp(k[i].section, section) && !strcmp(k[i].key, key))
					break;
			snprintf(msg, sizeof msg,
				 DOC ": section \"%s\", key %s: documented default %s", section,
				 key, want);
			TEST_ASSERT_TRUE_MESSAGE(i < nk,
						 msg); /* a default this test does not check */
			TEST_ASSERT_EQUAL_STRING_MESSAGE(k[i].actual, want, msg);
			seen[i] = true;
			checked++;
		}
	}
	for (int i = 0; i < nk; i++) {
		snprintf(msg, sizeof msg, DOC ": no default documented for %s / %s", k[i].section,
			 k[i].key);
		TEST_ASSERT_TRUE_MESSAGE(seen[i], msg);
	}
	TEST_ASSERT_EQUAL_INT(nk, checked);
}

/* ---- the line's object dictionary ------------------------------------------ */

/* "1014h / 1015h COB-ID EMCY / inhibit" -> indexes 1014h, 1015h */
static int parse_indexes(const char *cell, uint16_t *idx, int max)
{
	int n = 0;
	const char *p = cell;

	while (n < max) {
		char *end;
		unsigned long v = strtoul(p, &end, 16);
		if (end == p || *end != 'h' || v < 0x1000 || v > 0xFFFF)
			break;
		if (!strncmp(end + 1, "..", 2))
			return 0; /* a range ("1201h.. further SDO servers"): prose */
		idx[n++] = (uint16_t)v;
		p = end + 1;
		if (strncmp(p, " / ", 3) != 0)
			break;
		p += 3;
	}
	return n;
}

/* One default term: "0", "1 (on command)", "100h (...)", "80h + id",
 * "8000 0000h (not valid)", "`heartbeat_ms`". false for prose. */
static bool eval_term(const char *t, uint64_t *v)
{
	char buf[64];
	size_t n = 0;

	while (*t == ' ')
		t++;
	if (t[0] == '`') { /* a configuration key */
		const cogw_line_config *l = &cfg.lines[0];
		if (!strncmp(t, "`heartbeat_ms`", 14))
			return *v = l->heartbeat_ms, true;
		if (!strncmp(t, "`sync_period_us`", 16))
			return *v = l->sync_period_us, true;
		return false;
	}
	/* digits, hex digits and blanks up to an optional 'h' */
	while (*t && n < sizeof buf - 1 && (isxdigit((unsigned char)*t) || *t == ' ')) {
		if (*t != ' ')
			buf[n++] = *t;
		t++;
	}
	buf[n] = '\0';
	if (n == 0)
		return false;
	bool hex = *t == 'h';
	if (hex)
		t++;
	else
		for (size_t i = 0; i < n; i++)
			if (!isdigit((unsigned char)buf[i]))
				return false;
	*v = strtoull(buf, NULL, hex ? 16 : 10);
	while (*t == ' ')
		t++;
	if (!strncmp(t, "+ id", 4)) {
		*v += NODE_ID;
		t += 4;
		while (*t == ' ')
			t++;
	}
	return *t == '\0' || *t == '(';
}

/* The value subs of an object: sub 0 of a VAR, else 1..sub 0. */
static void check_object(uint16_t index, int only_sub, uint64_t want, const char *row)
{
	char msg[300];
	co_od *od = cfg.lines[0].od;
	co_od_entry *e0 = co_od_find(od, index, 0);
	int first = 0, last = 0;

	snprintf(msg, sizeof msg, DOC ": %04Xh: row \"%s\"", index, row);
	TEST_ASSERT_NOT_NULL_MESSAGE(e0, msg);
	if (co_od_find(od, index, 1)) { /* ARRAY / RECORD */
		first = 1;
		last = (int)co_od_entry_raw(e0);
	}
	if (only_sub >= 0)
		first = last = only_sub;
	for (int s = first; s <= last; s++) {
		co_od_entry *e = co_od_find(od, index, (uint8_t)s);
		snprintf(msg, sizeof msg, DOC ": %04Xh:%d: row \"%s\"", index, s, row);
		TEST_ASSERT_NOT_NULL_MESSAGE(e, msg);
		TEST_ASSERT_EQUAL_HEX64_MESSAGE(want, co_od_entry_raw(e), msg);
	}
}

static void test_od_table_matches_the_dictionary(void)
{
	int checked = 0, prose = 0;
	bool saw_1029 = false;

	doc = read_doc();
	for (char *line = strtok(doc, "\n"); line; line = strtok(NULL, "\n")) {
		char row[300];
		char *cells[8];
		uint16_t idx[4];
		uint64_t vals[4];
		int nv = 0;

		snprintf(row, sizeof row, "%s", line);
		if (split_row(line, cells, 8) != 3)
			continue;
		int ni = parse_indexes(cells[0], idx, 4);
		if (ni == 0)
			continue;
		/* "a / b" defaults */
		char dcell[200];
		snprintf(dcell, sizeof dcell, "%s", cells[2]);
		bool ok = true;
		for (char *t = dcell, *next; t && ok && nv < 4; t = next) {
			next = strstr(t, " / ");
			if (next) {
				*next = '\0';
				next += 3;
			}
			ok = eval_term(t, &vals[nv++]);
		}
		if (!ok) {
			prose++;
			continue;
		}
		if (nv == ni) { /* one default per object */
			for (int i = 0; i < ni; i++)
				check_object(idx[i], -1, vals[i], row);
		} else if (ni == 1 && nv > 1) { /* one per sub: "600h + id / 580h + id" */
			for (int i = 0; i < nv; i++)
				check_object(idx[0], i + 1, vals[i], row);
		} else if (nv == 1) { /* one default for all objects */
			for (int i = 0; i < ni; i++)
				check_object(idx[i], -1, vals[0], row);
		} else {
			TEST_FAIL_MESSAGE(row);
		}
		saw_1029 = saw_1029 || (ni == 1 && idx[0] == 0x1029);
		checked++;
	}
	TEST_ASSERT_TRUE_MESSAGE(saw_1029, DOC ": the 1029h row was not checked");
	/* the simple rows today: 1001h, 1003h, 1005h? (prose), 1006h/1007h,
	 * 100Ch/100Dh, 1010h/1011h, 1012h, 1014h/1015h, 1017h, 1019h,
	 * 1029h, 102Ah, 1200h, 1F2Ch, 1F2Fh */
	TEST_ASSERT_GREATER_OR_EQUAL_INT(12, checked);
	TEST_ASSERT_LESS_OR_EQUAL_INT(10, prose);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_key_tables_match_the_loader);
	RUN_TEST(test_od_table_matches_the_dictionary);
	return UNITY_END();
}
