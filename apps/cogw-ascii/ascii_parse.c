/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-ascii/ascii_parse.c - the CiA 309-3 command syntax. The
 * grammar is small enough for a hand-written scanner: a sequence number
 * in brackets, up to two numbers (net, node), a command word, its
 * arguments. A line that is not exactly one command is a syntax error
 * (101), never a guess: an extra token after a write's value would
 * otherwise be silently dropped.
 */
#include "apps/cogw-ascii/ascii_parse.h"

#include <errno.h>
#include <string.h>
#include <strings.h>

typedef struct scanner {
	const char *s;
	size_t n, pos;
} scanner;

typedef struct token {
	const char *p;
	size_t n;
} token;

static bool is_blank(char c)
{
	return c == ' ' || c == '\t';
}

/* Next blank-separated token; false at the end of the line or at a
 * comment. */
static bool next_token(scanner *sc, token *t)
{
	while (sc->pos < sc->n && is_blank(sc->s[sc->pos]))
		sc->pos++;
	if (sc->pos >= sc->n || sc->s[sc->pos] == '#')
		return false;
	t->p = sc->s + sc->pos;
	while (sc->pos < sc->n && !is_blank(sc->s[sc->pos]) && sc->s[sc->pos] != '#')
		sc->pos++;
	t->n = (size_t)(sc->s + sc->pos - t->p);
	return true;
}

static bool at_end(scanner *sc)
{
	token t;
	size_t save = sc->pos;
	bool more = next_token(sc, &t);

	sc->pos = save;
	return !more;
}

/* Command words are compared without regard to case, as the 309-3 tools
 * take them ("R", "READ", "Set Network"): scripts written for them must
 * work unchanged. */
static bool tok_is(const token *t, const char *word)
{
	return strlen(word) == t->n && strncasecmp(t->p, word, t->n) == 0;
}

/* The word, or a prefix of it of at least min characters ("preop" of
 * "preoperational", "r" of "read"). */
static bool tok_abbrev(const token *t, const char *word, size_t min)
{
	return t->n >= min && t->n <= strlen(word) && strncasecmp(t->p, word, t->n) == 0;
}

static bool tok_is_lss(const token *t)
{
	return t->n > 4 &&
	       (strncasecmp(t->p, "lss_", 4) == 0 || strncasecmp(t->p, "_lss_", 5) == 0);
}

static bool tok_number(const token *t, uint64_t *v)
{
	return ascii_number(t->p, t->n, v) == 0;
}

static bool tok_starts_number(const token *t)
{
	return t->n > 0 && t->p[0] >= '0' && t->p[0] <= '9';
}

/* A numeric argument within max; ASCII_E_SYNTAX if missing or bad. */
static int arg_number(scanner *sc, uint64_t max, uint32_t *out)
{
	token t;
	uint64_t v;

	if (!next_token(sc, &t) || !tok_number(&t, &v) || v > max)
		return ASCII_E_SYNTAX;
	*out = (uint32_t)v;
	return ASCII_OK;
}

static int parse_seq(scanner *sc, ascii_cmd *cmd)
{
	size_t i = sc->pos;
	uint64_t v;

	while (i < sc->n && is_blank(sc->s[i]))
		i++;
	if (i >= sc->n || sc->s[i] != '[')
		return ASCII_OK;
	size_t start = ++i;

	while (i < sc->n && sc->s[i] != ']')
		i++;
	if (i >= sc->n || ascii_number(sc->s + start, i - start, &v) != 0 || v > UINT32_MAX)
		return ASCII_E_SYNTAX;
	cmd->has_seq = true;
	cmd->seq = (uint32_t)v;
	sc->pos = i + 1;
	if (sc->pos < sc->n && !is_blank(sc->s[sc->pos]) && sc->s[sc->pos] != '#')
		return ASCII_E_SYNTAX;
	return ASCII_OK;
}

/* A vs value: the rest of the line, between double quotes with a quote
 * doubled, or unquoted (one word, as CANopenNode takes it). */
static int parse_vstring(scanner *sc, uint8_t *data, size_t cap, size_t *len)
{
	size_t out = 0;

	while (sc->pos < sc->n && is_blank(sc->s[sc->pos]))
		sc->pos++;
	if (sc->pos < sc->n && sc->s[sc->pos] == '"') {
		size_t i = sc->pos + 1;

		for (;;) {
			if (i >= sc->n)
				return ASCII_E_SYNTAX; /* unterminated */
			char c = sc->s[i++];

			if (c == '"') {
				if (i < sc->n && sc->s[i] == '"')
					i++;
				else
					break;
			}
			if (out >= cap)
				return ASCII_E_MEMORY;
			data[out++] = (uint8_t)c;
		}
		sc->pos = i;
		if (sc->pos < sc->n && !is_blank(sc->s[sc->pos]) && sc->s[sc->pos] != '#')
			return ASCII_E_SYNTAX;
	} else {
		token t;

		if (!next_token(sc, &t))
			return ASCII_E_SYNTAX;
		if (memchr(t.p, '"', t.n))
			return ASCII_E_SYNTAX;
		if (t.n > cap)
			return ASCII_E_MEMORY;
		memcpy(data, t.p, t.n);
		out = t.n;
	}
	*len = out;
	return ASCII_OK;
}

static int value_error(int rc)
{
	return rc == -E2BIG ? ASCII_E_MEMORY : ASCII_E_SYNTAX;
}

static int parse_sdo(scanner *sc, ascii_cmd *cmd, bool write, uint8_t *data, size_t cap)
{
	token t;
	uint64_t v;

	if (!next_token(sc, &t) || !tok_number(&t, &v) || v > 0xFFFF)
		return ASCII_E_SYNTAX;
	cmd->index = (uint16_t)v;
	if (!next_token(sc, &t) || !tok_number(&t, &v) || v > 0xFF)
		return ASCII_E_SYNTAX;
	cmd->sub = (uint8_t)v;
	if (!next_token(sc, &t)) {
		if (write)
			return ASCII_E_SYNTAX;
		return ASCII_OK; /* read without a type: hex */
	}
	cmd->type = ascii_type_find(t.p, t.n);
	if (!cmd->type)
		return ASCII_E_SYNTAX;
	if (!write)
		return at_end(sc) ? ASCII_OK : ASCII_E_SYNTAX;
	if (cmd->type->kind == ASCII_K_VSTRING) {
		int rc = parse_vstring(sc, data, cap, &cmd->data_len);

		if (rc)
			return rc;
	} else if (cmd->type->kind == ASCII_K_TIME || cmd->type->kind == ASCII_K_HEXBYTES) {
		/* several words: the rest of the line up to a comment */
		token first, last;
		int rc;

		if (!next_token(sc, &first))
			return ASCII_E_SYNTAX;
		last = first;
		while (next_token(sc, &t))
			last = t;
		rc = ascii_value_encode(cmd->type, first.p, (size_t)(last.p + last.n - first.p),
					data, cap, &cmd->data_len);
		if (rc)
			return value_error(rc);
	} else {
		int rc;

		if (!next_token(sc, &t))
			return ASCII_E_SYNTAX;
		rc = ascii_value_encode(cmd->type, t.p, t.n, data, cap, &cmd->data_len);
		if (rc)
			return value_error(rc);
	}
	return at_end(sc) ? ASCII_OK : ASCII_E_SYNTAX;
}

static int parse_set(scanner *sc, ascii_cmd *cmd)
{
	token t;

	if (cmd->node >= 0) /* [net] set ...: a node makes no sense here */
		return ASCII_E_SYNTAX;
	if (!next_token(sc, &t))
		return ASCII_E_SYNTAX;
	if (tok_is(&t, "network")) {
		cmd->verb = ASCII_V_SET_NETWORK;
		if (arg_number(sc, UINT32_MAX, &cmd->args[0]))
			return ASCII_E_SYNTAX;
		if (cmd->args[0] < 1 || cmd->args[0] > 127)
			return ASCII_E_NET;
	} else if (tok_is(&t, "node")) {
		cmd->verb = ASCII_V_SET_NODE;
		if (arg_number(sc, UINT32_MAX, &cmd->args[0]))
			return ASCII_E_SYNTAX;
		if (cmd->args[0] < 1 || cmd->args[0] > 127)
			return ASCII_E_NODE;
	} else if (tok_is(&t, "sdo_timeout")) {
		cmd->verb = ASCII_V_SET_SDO_TIMEOUT;
		if (arg_number(sc, 600000, &cmd->args[0]) || cmd->args[0] == 0)
			return ASCII_E_SYNTAX;
	} else if (tok_is(&t, "sdo_block")) {
		cmd->verb = ASCII_V_SET_SDO_BLOCK;
		if (arg_number(sc, 1, &cmd->args[0]))
			return ASCII_E_SYNTAX;
	} else {
		return ASCII_E_UNSUPPORTED;
	}
	cmd->n_args = 1;
	return at_end(sc) ? ASCII_OK : ASCII_E_SYNTAX;
}

typedef struct lss_syntax {
	const char *word;
	ascii_verb verb;
	uint8_t min_args, max_args;
	uint32_t max; /* of every argument */
} lss_syntax;

static const lss_syntax lss_words[] = {
	{ "lss_switch_glob", ASCII_V_LSS_SWITCH_GLOB, 1, 1, 1 },
	{ "lss_switch_sel", ASCII_V_LSS_SWITCH_SEL, 4, 4, UINT32_MAX },
	{ "lss_set_node", ASCII_V_LSS_SET_NODE, 1, 1, 255 },
	{ "lss_conf_bitrate", ASCII_V_LSS_CONF_BITRATE, 2, 2, 255 },
	{ "lss_activate_bitrate", ASCII_V_LSS_ACTIVATE_BITRATE, 1, 1, 0xFFFF },
	{ "lss_store", ASCII_V_LSS_STORE, 0, 0, 0 },
	{ "lss_inquire_addr", ASCII_V_LSS_INQUIRE_ADDR, 0, 1, 3 },
	{ "lss_get_node", ASCII_V_LSS_GET_NODE, 0, 0, 0 },
	{ "_lss_fastscan", ASCII_V_LSS_FASTSCAN, 0, 1, 60000 },
	{ "lss_ident_nonconf", ASCII_V_LSS_IDENT_NONCONF, 0, 0, 0 },
	{ NULL, ASCII_V_NONE, 0, 0, 0 },
};

static int parse_lss(scanner *sc, const token *word, ascii_cmd *cmd)
{
	const lss_syntax *l = lss_words;
	token t;
	uint64_t v;

	while (l->word && !tok_is(word, l->word))
		l++;
	if (!l->word)
		return ASCII_E_UNSUPPORTED; /* lss_allnodes and friends */
	if (cmd->node >= 0)
		return ASCII_E_SYNTAX; /* [net] lss_...: LSS addresses no node id */
	cmd->verb = l->verb;
	while (next_token(sc, &t)) {
		if (cmd->n_args >= l->max_args || !tok_number(&t, &v) || v > l->max)
			return ASCII_E_SYNTAX;
		cmd->args[cmd->n_args++] = (uint32_t)v;
	}
	return cmd->n_args >= l->min_args ? ASCII_OK : ASCII_E_SYNTAX;
}

static int parse_events(scanner *sc, ascii_cmd *cmd)
{
	static const struct {
		const char *name;
		uint32_t bit;
	} classes[] = { { "emcy", ASCII_EV_EMCY },       { "boot", ASCII_EV_BOOT },
			{ "hb", ASCII_EV_HB },           { "nmt", ASCII_EV_NMT },
			{ "manager", ASCII_EV_MANAGER }, { "all", ASCII_EV_ALL } };
	token t;

	if (!next_token(sc, &t))
		return ASCII_E_SYNTAX;
	if (tok_is(&t, "on"))
		cmd->events_on = true;
	else if (!tok_is(&t, "off"))
		return ASCII_E_SYNTAX;
	cmd->verb = ASCII_V_EVENTS;
	while (next_token(sc, &t)) {
		size_t i = 0;

		while (i < sizeof classes / sizeof classes[0] && !tok_is(&t, classes[i].name))
			i++;
		if (i == sizeof classes / sizeof classes[0])
			return ASCII_E_SYNTAX;
		cmd->events |= classes[i].bit;
	}
	if (!cmd->events)
		cmd->events = ASCII_EV_ALL;
	return ASCII_OK;
}

static int parse_nmt(scanner *sc, const token *w, ascii_cmd *cmd)
{
	token t;

	if (tok_is(w, "start"))
		cmd->verb = ASCII_V_NMT_START;
	else if (tok_is(w, "stop"))
		cmd->verb = ASCII_V_NMT_STOP;
	else if (tok_abbrev(w, "preoperational", 5))
		cmd->verb = ASCII_V_NMT_PREOP;
	else if (tok_is(w, "reset")) {
		if (!next_token(sc, &t))
			return ASCII_E_SYNTAX;
		if (tok_is(&t, "node"))
			cmd->verb = ASCII_V_NMT_RESET_NODE;
		else if (tok_abbrev(&t, "communication", 4))
			cmd->verb = ASCII_V_NMT_RESET_COMM;
		else
			return ASCII_E_SYNTAX;
	} else
		return ASCII_E_UNSUPPORTED;
	return at_end(sc) ? ASCII_OK : ASCII_E_SYNTAX;
}

static int parse_command(scanner *sc, const token *w, ascii_cmd *cmd, uint8_t *data, size_t cap)
{
	token t;

	if (tok_abbrev(w, "read", 1)) {
		cmd->verb = ASCII_V_READ;
		return parse_sdo(sc, cmd, false, data, cap);
	}
	if (tok_abbrev(w, "write", 1)) {
		cmd->verb = ASCII_V_WRITE;
		return parse_sdo(sc, cmd, true, data, cap);
	}
	if (tok_is(w, "set"))
		return parse_set(sc, cmd);
	if (tok_is_lss(w))
		return parse_lss(sc, w, cmd);
	if (tok_is(w, "info")) {
		if (cmd->net >= 0 || cmd->node >= 0)
			return ASCII_E_SYNTAX;
		if (!next_token(sc, &t) || !tok_is(&t, "version"))
			return ASCII_E_UNSUPPORTED;
		cmd->verb = ASCII_V_INFO_VERSION;
		return at_end(sc) ? ASCII_OK : ASCII_E_SYNTAX;
	}
	if (tok_is(w, "help")) {
		if (cmd->net >= 0 || cmd->node >= 0)
			return ASCII_E_SYNTAX;
		cmd->verb = ASCII_V_HELP;
		if (next_token(sc, &t)) {
			if (tok_is(&t, "datatype"))
				cmd->help_topic = 1;
			else if (tok_is(&t, "lss"))
				cmd->help_topic = 2;
			else
				return ASCII_E_SYNTAX;
		}
		return at_end(sc) ? ASCII_OK : ASCII_E_SYNTAX;
	}
	if (tok_is(w, "events")) {
		if (cmd->node >= 0)
			return ASCII_E_SYNTAX;
		return parse_events(sc, cmd);
	}
	return parse_nmt(sc, w, cmd);
}

int ascii_parse(const char *line, size_t len, ascii_cmd *cmd, uint8_t *data, size_t cap)
{
	scanner sc = { .s = line, .n = len };
	token t[3];
	uint64_t v[2];
	unsigned nums = 0;
	int rc;

	memset(cmd, 0, sizeof *cmd);
	cmd->net = -1;
	cmd->node = -1;
	rc = parse_seq(&sc, cmd);
	if (rc)
		return rc;
	if (memchr(line, '\0', len))
		return ASCII_E_SYNTAX; /* after the sequence number: the error line echoes it */
	if (!next_token(&sc, &t[0]))
		return cmd->has_seq ? ASCII_E_SYNTAX : ASCII_OK; /* "[5]" alone says nothing */
	/* [[net] node]: numbers (or "all" for the node) before the word */
	while (nums < 2 && (tok_starts_number(&t[nums]) || tok_is(&t[nums], "all"))) {
		if (tok_is(&t[nums], "all"))
			v[nums] = 0;
		else if (!tok_number(&t[nums], &v[nums]))
			return ASCII_E_SYNTAX;
		nums++;
		if (!next_token(&sc, &t[nums]))
			return ASCII_E_SYNTAX;
	}
	if (nums == 2) {
		if (tok_is(&t[0], "all"))
			return ASCII_E_SYNTAX;
		if (v[0] < 1 || v[0] > 127)
			return ASCII_E_NET;
		cmd->net = (int)v[0];
	}
	if (nums >= 1) {
		uint64_t node = v[nums - 1];

		if (node > 127)
			return ASCII_E_NODE;
		cmd->node = (int)node;
	}
	/* "[net] set/lss_..." carry one number, which is the net */
	if (nums == 1 && (tok_is(&t[1], "set") || tok_is_lss(&t[1]) || tok_is(&t[1], "events"))) {
		if (tok_is(&t[0], "all"))
			return ASCII_E_SYNTAX;
		if (v[0] < 1 || v[0] > 127)
			return ASCII_E_NET;
		cmd->net = (int)v[0];
		cmd->node = -1;
	}
	if (tok_starts_number(&t[nums]))
		return ASCII_E_SYNTAX; /* a third number */
	rc = parse_command(&sc, &t[nums], cmd, data, cap);
	if (rc)
		return rc;
	if (cmd->node == 0 && (cmd->verb == ASCII_V_READ || cmd->verb == ASCII_V_WRITE))
		return ASCII_E_NODE; /* SDO needs one node: 0 is "all" only for NMT */
	return ASCII_OK;
}

const char *ascii_verb_to_string(ascii_verb v)
{
	static const char *const names[] = {
		[ASCII_V_NONE] = "none",
		[ASCII_V_READ] = "read",
		[ASCII_V_WRITE] = "write",
		[ASCII_V_NMT_START] = "start",
		[ASCII_V_NMT_STOP] = "stop",
		[ASCII_V_NMT_PREOP] = "preop",
		[ASCII_V_NMT_RESET_NODE] = "reset node",
		[ASCII_V_NMT_RESET_COMM] = "reset comm",
		[ASCII_V_SET_NETWORK] = "set network",
		[ASCII_V_SET_NODE] = "set node",
		[ASCII_V_SET_SDO_TIMEOUT] = "set sdo_timeout",
		[ASCII_V_SET_SDO_BLOCK] = "set sdo_block",
		[ASCII_V_LSS_SWITCH_GLOB] = "lss_switch_glob",
		[ASCII_V_LSS_SWITCH_SEL] = "lss_switch_sel",
		[ASCII_V_LSS_SET_NODE] = "lss_set_node",
		[ASCII_V_LSS_CONF_BITRATE] = "lss_conf_bitrate",
		[ASCII_V_LSS_ACTIVATE_BITRATE] = "lss_activate_bitrate",
		[ASCII_V_LSS_STORE] = "lss_store",
		[ASCII_V_LSS_INQUIRE_ADDR] = "lss_inquire_addr",
		[ASCII_V_LSS_GET_NODE] = "lss_get_node",
		[ASCII_V_LSS_FASTSCAN] = "_lss_fastscan",
		[ASCII_V_LSS_IDENT_NONCONF] = "lss_ident_nonconf",
		[ASCII_V_INFO_VERSION] = "info version",
		[ASCII_V_HELP] = "help",
		[ASCII_V_EVENTS] = "events",
	};

	return (unsigned)v < sizeof names / sizeof names[0] && names[v] ? names[v] : "?";
}

bool ascii_verb_writes(ascii_verb v)
{
	switch (v) {
	case ASCII_V_NONE:
	case ASCII_V_READ:
	case ASCII_V_SET_NETWORK:
	case ASCII_V_SET_NODE:
	case ASCII_V_SET_SDO_TIMEOUT:
	case ASCII_V_SET_SDO_BLOCK:
	case ASCII_V_INFO_VERSION:
	case ASCII_V_HELP:
	case ASCII_V_EVENTS:
		return false;
	default:
		return true;
	}
}
