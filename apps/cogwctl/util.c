/* SPDX-License-Identifier: MIT */
/*
 * apps/cogwctl/util.c - option parsing, output, strict argument and value
 * parsing for cogwctl. Values are checked completely before anything is
 * sent: a typo must never reach a device as a different number.
 */
#include "apps/cogwctl/ctl.h"

#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <math.h>
#include <mqueue.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

#include "apps/common/json_util.h"
#include "core/sdo.h"

/* ---- options ------------------------------------------------------------- */

static const char *opt_value(int argc, char **argv, int *i, const char *arg, const char *name,
			     bool *missing)
{
	size_t n = strlen(name);
	*missing = false;
	if (arg[n] == '=')
		return arg + n + 1;
	if (*i + 1 >= argc) {
		*missing = true;
		return NULL;
	}
	return argv[++*i];
}

/* "--name" or "--name=..." */
static bool opt_is(const char *arg, const char *name)
{
	size_t n = strlen(name);
	return strncmp(arg, name, n) == 0 && (arg[n] == '\0' || arg[n] == '=');
}

int ctl_global_option(ctl *c, int argc, char **argv, int *i)
{
	const char *a = argv[*i];
	bool missing;
	const char *v;
	if (strcmp(a, "--json") == 0 || strcmp(a, "-j") == 0) {
		c->json = true;
		return 1;
	}
	if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
		c->help = true;
		return 1;
	}
	if (opt_is(a, "--instance")) {
		v = opt_value(argc, argv, i, a, "--instance", &missing);
		if (missing || !mbx_instance_is_valid(v)) {
			ctl_usage_error(c,
					"--instance needs a name of 1..%u characters [A-Za-z0-9_-]",
					MBX_INSTANCE_MAX - 1);
			return -1;
		}
		c->instance = v;
		return 1;
	}
	if (opt_is(a, "--timeout")) {
		uint64_t ms;
		const char *err;
		v = opt_value(argc, argv, i, a, "--timeout", &missing);
		if (missing || ctl_parse_u64(v, 3600000, &ms, &err) < 0 || ms == 0) {
			ctl_usage_error(c, "--timeout needs milliseconds 1..3600000");
			return -1;
		}
		c->timeout_ms = (unsigned)ms;
		return 1;
	}
	return 0;
}

static bool looks_negative_number(const char *a)
{
	return a[0] == '-' &&
	       (isdigit((unsigned char)a[1]) || (a[1] == '.' && isdigit((unsigned char)a[2])));
}

int ctl_parse(ctl *c, int argc, char **argv, const ctl_opt *opts, const char **pos, int max_pos,
	      int *n_pos)
{
	bool only_pos = false;
	*n_pos = 0;
	for (int i = 1; i < argc; i++) {
		const char *a = argv[i];
		if (!only_pos && strcmp(a, "--") == 0) {
			only_pos = true;
			continue;
		}
		if (!only_pos && a[0] == '-' && a[1] && !looks_negative_number(a)) {
			int g = ctl_global_option(c, argc, argv, &i);
			if (g < 0)
				return CTL_EXIT_USAGE;
			if (g > 0)
				continue;
			const ctl_opt *o = opts;
			for (; o && o->name; o++)
				if (opt_is(a, o->name))
					break;
			if (!o || !o->name)
				return ctl_usage_error(c, "unknown option '%s'", a);
			if (o->has_arg) {
				bool missing;
				const char *v = opt_value(argc, argv, &i, a, o->name, &missing);
				if (missing)
					return ctl_usage_error(c, "%s needs a value", o->name);
				*o->value = v;
			} else {
				if (a[strlen(o->name)] == '=')
					return ctl_usage_error(c, "%s takes no value", o->name);
				*o->flag = true;
			}
			continue;
		}
		if (*n_pos >= max_pos)
			return ctl_usage_error(c, "unexpected argument '%s'", a);
		pos[(*n_pos)++] = a;
	}
	return 0;
}

/* ---- output -------------------------------------------------------------- */

int ctl_usage_error(ctl *c, const char *fmt, ...)
{
	va_list ap;
	fprintf(stderr, "cogwctl%s%s: ", c->what ? " " : "", c->what ? c->what : "");
	va_start(ap, fmt);
	vfprintf(stderr, fmt, ap);
	va_end(ap);
	fprintf(stderr, "\n(see 'cogwctl%s%s --help')\n", c->what ? " " : "",
		c->what ? c->what : "");
	return CTL_EXIT_USAGE;
}

const char *ctl_abort_text(uint32_t abort, char *buf, size_t len)
{
	snprintf(buf, len, "0x%08" PRIX32 " (%s)", abort, sdo_abort_to_string(abort));
	return buf;
}

int ctl_exit_of(int rc, uint32_t abort)
{
	if (rc >= 0)
		return CTL_EXIT_OK;
	switch (rc) {
	case COGW_E_NO_DAEMON:
		return CTL_EXIT_NO_DAEMON;
	case COGW_E_TIMEOUT:
	case COGW_E_NO_ANSWER:
		return CTL_EXIT_TIMEOUT;
	case COGW_E_ABORT:
		/* the device did not answer in time: a timeout, not a refusal */
		return abort == SDO_AB_TIMEOUT ? CTL_EXIT_TIMEOUT : CTL_EXIT_REFUSED;
	default:
		return CTL_EXIT_REFUSED;
	}
}

int ctl_fail(ctl *c, int rc, uint32_t abort, const char *context)
{
	char ab[160] = "";
	const char *hint = "";
	/* Who did not answer: the daemon (libcogw's own timeout: COGW_E_TIMEOUT
	 * with no answer at all) or the device (the daemon answered with
	 * NO_ANSWER, or an SDO abort 0x05040000). Both exit 4; the text and
	 * the JSON "timeout" field tell them apart. */
	const char *who = NULL;
	if (rc == COGW_E_ABORT)
		ctl_abort_text(abort, ab, sizeof ab);
	if (rc == COGW_E_NO_DAEMON) {
		hint = " (is cogwd running, with this mailbox instance and line?)";
	} else if (rc == COGW_E_TIMEOUT) {
		hint = " (the daemon did not answer in time; --timeout MS)";
		who = "daemon";
	} else if (rc == COGW_E_NO_ANSWER) {
		hint = " (the daemon answered: the device did not answer on the bus)";
		who = "device";
	} else if (rc == COGW_E_ABORT && abort == SDO_AB_TIMEOUT) {
		hint = " (the daemon answered: the device did not answer on the bus in time)";
		who = "device";
	}
	if (c->json) {
		cJSON *o = cJSON_CreateObject();
		cJSON_AddBoolToObject(o, "ok", false);
		cJSON_AddStringToObject(o, "command", c->what ? c->what : "");
		cJSON_AddStringToObject(o, "context", context);
		cJSON_AddNumberToObject(o, "status", rc);
		cJSON_AddStringToObject(o, "error", cogw_strerror(rc));
		if (rc == COGW_E_ABORT) {
			char hex[16];
			snprintf(hex, sizeof hex, "0x%08" PRIX32, abort);
			cJSON_AddStringToObject(o, "abort", hex);
			cJSON_AddStringToObject(o, "abort_text", sdo_abort_to_string(abort));
		}
		if (who)
			cJSON_AddStringToObject(o, "timeout", who);
		cJSON_AddNumberToObject(o, "exit", ctl_exit_of(rc, abort));
		ctl_json_print(o);
	} else if (rc == COGW_E_ABORT) {
		fprintf(stderr, "cogwctl: %s: abort %s%s\n", context, ab, hint);
	} else {
		fprintf(stderr, "cogwctl: %s: %s%s\n", context, cogw_strerror(rc), hint);
	}
	return ctl_exit_of(rc, abort);
}

void ctl_json_print(cJSON *o)
{
	char *s = cJSON_PrintUnformatted(o);
	if (s) {
		puts(s);
		free(s);
	}
	fflush(stdout);
	cJSON_Delete(o);
}

cogw *ctl_handle(ctl *c, int *exit_code)
{
	if (c->h)
		return c->h;
	cogw_options o = { .instance = c->instance, .timeout_ms = c->timeout_ms };
	int rc = cogw_open_opts(&c->h, &o);
	if (rc < 0) {
		char cause[128] = ""; /* only a system error leaves errno to name it */

		if (rc == COGW_E_SYSTEM)
			snprintf(cause, sizeof cause, " (%s)", strerror(errno));
		fprintf(stderr, "cogwctl: cannot create the client message queues: %s%s\n",
			cogw_strerror(rc), cause);
		*exit_code = CTL_EXIT_NO_DAEMON;
		c->h = NULL;
	}
	return c->h;
}

void ctl_timestamp(char *buf, size_t len, double *epoch_s)
{
	struct timeval tv;
	struct tm tm;
	gettimeofday(&tv, NULL);
	localtime_r(&tv.tv_sec, &tm);
	snprintf(buf, len, "%02d:%02d:%02d.%03ld", tm.tm_hour, tm.tm_min, tm.tm_sec,
		 (long)(tv.tv_usec / 1000));
	if (epoch_s)
		*epoch_s = (double)tv.tv_sec + (double)tv.tv_usec / 1e6;
}

/* ---- numbers ------------------------------------------------------------- */

int ctl_parse_u64(const char *s, uint64_t max, uint64_t *v, const char **err)
{
	if (!s || !*s || isspace((unsigned char)*s) || *s == '-' || *s == '+') {
		*err = "not a non-negative integer";
		return -1;
	}
	bool hex = s[0] == '0' && (s[1] == 'x' || s[1] == 'X');
	char *end;
	errno = 0;
	unsigned long long x = strtoull(s, &end, hex ? 16 : 10);
	if (end == s || *end || (hex && s[2] == '\0')) {
		*err = "not an integer (decimal, or hex with 0x)";
		return -1;
	}
	if (errno == ERANGE || x > max) {
		*err = "out of range";
		return -1;
	}
	*v = x;
	return 0;
}

int ctl_parse_i64(const char *s, int64_t min, int64_t max, int64_t *v, const char **err)
{
	if (!s || !*s) {
		*err = "not an integer";
		return -1;
	}
	bool neg = s[0] == '-';
	uint64_t mag;
	if (ctl_parse_u64(s + (neg || s[0] == '+'), UINT64_MAX, &mag, err) < 0)
		return -1;
	if (neg ? mag > (uint64_t)INT64_MAX + 1u : mag > (uint64_t)INT64_MAX) {
		*err = "out of range";
		return -1;
	}
	int64_t x = neg ? (int64_t)(0 - mag) : (int64_t)mag;
	if (x < min || x > max) {
		*err = "out of range";
		return -1;
	}
	*v = x;
	return 0;
}

int ctl_arg_uint(ctl *c, const char *s, const char *name, uint64_t max, uint64_t *v)
{
	const char *err;
	if (ctl_parse_u64(s, max, v, &err) < 0) {
		ctl_usage_error(c, "%s '%s': %s (0..%" PRIu64 ")", name, s, err, max);
		return -1;
	}
	return 0;
}

int ctl_arg_line(ctl *c, const char *s, unsigned *line)
{
	uint64_t v;
	if (ctl_arg_uint(c, s, "LINE", MBX_LINES_MAX - 1, &v) < 0)
		return -1;
	*line = (unsigned)v;
	return 0;
}

int ctl_arg_node(ctl *c, const char *s, uint8_t *node)
{
	uint64_t v;
	const char *err;
	if (ctl_parse_u64(s, 127, &v, &err) < 0 || v == 0) {
		ctl_usage_error(c, "NODE '%s': a node-ID is 1..127", s);
		return -1;
	}
	*node = (uint8_t)v;
	return 0;
}

int ctl_arg_index(ctl *c, const char *s, uint16_t *index)
{
	/* CANopen indexes are hex by convention: "1018", "0x1018", "1018h" */
	char buf[16];
	size_t n = strlen(s);
	const char *p = s;
	if (n >= 2 && p[0] == '0' && (p[1] == 'x' || p[1] == 'X')) {
		p += 2;
		n -= 2;
	}
	if (n == 0 || n >= sizeof buf)
		goto bad;
	memcpy(buf, p, n + 1);
	if (buf[n - 1] == 'h' || buf[n - 1] == 'H')
		buf[--n] = '\0';
	if (n == 0 || n > 4)
		goto bad;
	for (size_t i = 0; i < n; i++)
		if (!isxdigit((unsigned char)buf[i]))
			goto bad;
	*index = (uint16_t)strtoul(buf, NULL, 16);
	return 0;
bad:
	ctl_usage_error(c, "INDEX '%s': an object index is hex 0000..FFFF (\"1018\", \"0x1018\")",
			s);
	return -1;
}

int ctl_arg_sub(ctl *c, const char *s, uint8_t *sub)
{
	uint64_t v;
	if (ctl_arg_uint(c, s, "SUB", 255, &v) < 0)
		return -1;
	*sub = (uint8_t)v;
	return 0;
}

int ctl_parse_hex_bytes(const char *s, uint8_t *out, size_t cap, size_t *n, const char **err)
{
	size_t k = 0;
	const char *p = s;
	if (p[0] == '0' && (p[1] == 'x' || p[1] == 'X'))
		p += 2;
	while (*p) {
		if (*p == ' ' || *p == ':' || *p == '.' || *p == '-') {
			p++;
			continue;
		}
		if (!isxdigit((unsigned char)p[0]) || !isxdigit((unsigned char)p[1])) {
			*err = "not a hex byte string (pairs of hex digits, optionally separated "
			       "by spaces, ':' or '.')";
			return -1;
		}
		if (k >= cap) {
			*err = "too many bytes";
			return -1;
		}
		char two[3] = { p[0], p[1], 0 };
		out[k++] = (uint8_t)strtoul(two, NULL, 16);
		p += 2;
	}
	*n = k;
	return 0;
}

int ctl_read_file(ctl *c, const char *path, uint8_t **data, size_t *len)
{
	FILE *f = fopen(path, "rb");
	if (!f) {
		fprintf(stderr, "cogwctl %s: %s: %s\n", c->what ? c->what : "", path,
			strerror(errno));
		return CTL_EXIT_USAGE;
	}
	size_t cap = 4096, n = 0;
	uint8_t *buf = malloc(cap);
	for (;;) {
		if (!buf) {
			fclose(f);
			fprintf(stderr, "cogwctl: out of memory reading %s\n", path);
			return CTL_EXIT_REFUSED;
		}
		size_t got = fread(buf + n, 1, cap - n, f);
		n += got;
		if (got == 0)
			break;
		if (n == cap) {
			cap *= 2;
			uint8_t *nb = realloc(buf, cap);
			if (!nb)
				free(buf);
			buf = nb;
		}
	}
	bool failed = ferror(f);
	fclose(f);
	if (failed) {
		free(buf);
		fprintf(stderr, "cogwctl %s: %s: read error\n", c->what ? c->what : "", path);
		return CTL_EXIT_USAGE;
	}
	*data = buf;
	*len = n;
	return 0;
}

/* ---- types and values ---------------------------------------------------- */

const ctl_type *ctl_type_find(const char *name)
{
	return cogw_type_find(name);
}

const char *ctl_type_names(void)
{
	return cogw_type_names();
}

/* Why a VALUE is not one of type t (rc from cogw_value_parse). */
static int value_error(ctl *c, const ctl_type *t, const char *value, int rc)
{
	unsigned bits = t->size * 8u;
	if (t->type == CO_T_BOOLEAN)
		return ctl_usage_error(c, "VALUE '%s' for bool: use 0, 1, true or false", value);
	if (t->type == CO_T_REAL32 || t->type == CO_T_REAL64)
		return ctl_usage_error(c, "VALUE '%s' for %s: not a finite number%s", value,
				       t->name, t->type == CO_T_REAL32 ? " within +-3.4e38" : "");
	if (t->type == CO_T_TIME_OF_DAY || t->type == CO_T_TIME_DIFFERENCE)
		return ctl_usage_error(c, "VALUE '%s' for %s: give \"DAYS MS\"", value, t->name);
	if (rc != COGW_E_PARAM)
		return ctl_usage_error(c, "VALUE '%s' for %s: not an integer", value, t->name);
	if (co_type_is_signed(t->type))
		return ctl_usage_error(
			c, "VALUE '%s' for %s: out of range (%" PRId64 "..%" PRId64 ")", value,
			t->name, bits == 64 ? INT64_MIN : -((int64_t)1 << (bits - 1)),
			bits == 64 ? INT64_MAX : ((int64_t)1 << (bits - 1)) - 1);
	return ctl_usage_error(c, "VALUE '%s' for %s: out of range (0..%" PRIu64 ")", value,
			       t->name, bits == 64 ? UINT64_MAX : ((uint64_t)1 << bits) - 1);
}

int ctl_value_encode(ctl *c, const ctl_type *t, const char *value, uint8_t **data, size_t *len)
{
	const char *err = NULL;
	*data = NULL;
	*len = 0;
	if (t->size == 0) {
		if (value[0] == '@')
			return ctl_read_file(c, value + 1, data, len);
		if (t->type == CO_T_VISIBLE_STRING) {
			size_t n = strlen(value);
			*data = malloc(n ? n : 1);
			memcpy(*data, value, n);
			*len = n;
			return 0;
		}
		size_t cap = strlen(value) / 2 + 1;
		*data = malloc(cap);
		if (ctl_parse_hex_bytes(value, *data, cap, len, &err) < 0) {
			free(*data);
			*data = NULL;
			return ctl_usage_error(c, "VALUE '%s' for %s: %s (or @FILE)", value,
					       t->name, err);
		}
		return 0;
	}
	uint8_t buf[8] = { 0 };
	size_t n = 0;
	int rc = cogw_value_parse(t->type, value, buf, sizeof buf, &n);
	if (rc < 0)
		return value_error(c, t, value, rc);
	*data = malloc(t->size);
	memcpy(*data, buf, t->size);
	*len = t->size;
	return 0;
}

char *ctl_hex_text(const uint8_t *data, size_t len, size_t max)
{
	size_t shown = len < max ? len : max;
	char *s = malloc(shown * 3 + 8);
	size_t off = 0;
	for (size_t i = 0; i < shown; i++)
		off += (size_t)sprintf(s + off, "%s%02x", i ? " " : "", data[i]);
	if (shown < len)
		strcpy(s + off, " ...");
	else
		s[off] = '\0';
	return s;
}

static uint64_t le_uint(const uint8_t *d, size_t n)
{
	uint64_t v = 0;
	for (size_t i = 0; i < n; i++)
		v |= (uint64_t)d[i] << (8 * i);
	return v;
}

static int64_t le_int(const uint8_t *d, size_t n)
{
	uint64_t v = le_uint(d, n);
	if (n < 8 && (v & ((uint64_t)1 << (n * 8 - 1))))
		v |= ~(((uint64_t)1 << (n * 8)) - 1); /* sign-extend */
	return (int64_t)v;
}

static bool printable(const uint8_t *d, size_t n)
{
	if (!n)
		return false;
	for (size_t i = 0; i < n; i++)
		if (d[i] < 0x20 || d[i] > 0x7E)
			return false;
	return true;
}

char *ctl_value_text(const ctl_type *t, const uint8_t *data, size_t len)
{
	char *s = NULL;
	if (!t) {
		char *hex = ctl_hex_text(data, len, 64);
		if (len == 1 || len == 2 || len == 4 || len == 8) {
			if (asprintf(&s, "%s (= %" PRIu64 " as u%zu)", hex, le_uint(data, len),
				     len * 8) < 0)
				s = NULL;
		} else if (printable(data, len) && len <= 256) {
			if (asprintf(&s, "%s (\"%.*s\")", hex, (int)len, (const char *)data) < 0)
				s = NULL;
		} else {
			return hex;
		}
		free(hex);
		return s;
	}
	if (t->size == 0) {
		if (t->type == CO_T_VISIBLE_STRING) {
			s = malloc(len + 1);
			memcpy(s, data, len);
			s[len] = '\0';
			return s;
		}
		return ctl_hex_text(data, len, 64);
	}
	char text[64];
	int r = cogw_value_format(t->type, data, len, text, sizeof text);
	if (r < 0)
		return NULL;
	if (co_type_is_signed(t->type) || t->type == CO_T_BOOLEAN || t->type == CO_T_REAL32 ||
	    t->type == CO_T_REAL64 || t->type == CO_T_TIME_OF_DAY ||
	    t->type == CO_T_TIME_DIFFERENCE)
		r = asprintf(&s, "%s",
			     t->type == CO_T_BOOLEAN ? (data[0] ? "true" : "false") : text);
	else
		r = asprintf(&s, "%s (0x%0*" PRIX64 ")", text, t->size * 2, le_uint(data, t->size));
	return r < 0 ? NULL : s;
}

void ctl_json_add_real(cJSON *o, const char *name, uint16_t type, const uint8_t *data)
{
	/* cJSON prints a number with 15 digits when that reads back "close
	 * enough": some doubles need 17. The text that reads back to the
	 * same bits goes in as it is; NaN and infinities have no JSON number
	 * (null, as cJSON gives them). */
	char num[40];
	if (cogw_value_format(type, data, type == CO_T_REAL32 ? 4 : 8, num, sizeof num) > 0 &&
	    isfinite(strtod(num, NULL)))
		cJSON_AddItemToObject(o, name, json_util_real_number(num));
	else
		cJSON_AddNullToObject(o, name);
}

void ctl_value_json(cJSON *o, const ctl_type *t, const uint8_t *data, size_t len)
{
	char *hex = ctl_hex_text(data, len, len);
	cJSON_AddStringToObject(o, "hex", hex);
	free(hex);
	if (!t) {
		if (len == 1 || len == 2 || len == 4 || len == 8)
			cJSON_AddNumberToObject(o, "uint_guess", (double)le_uint(data, len));
		return;
	}
	cJSON_AddStringToObject(o, "type", t->name);
	if (t->size == 0) {
		if (t->type == CO_T_VISIBLE_STRING) {
			char *s = malloc(len + 1);
			memcpy(s, data, len);
			s[len] = '\0';
			cJSON_AddStringToObject(o, "value", s);
			free(s);
		}
		return;
	}
	if (t->type == CO_T_BOOLEAN) {
		cJSON_AddBoolToObject(o, "value", data[0] != 0);
	} else if (t->type == CO_T_REAL32 || t->type == CO_T_REAL64) {
		ctl_json_add_real(o, "value", t->type, data);
	} else if (t->size > 6) {
		/* beyond 2^53 a JSON number loses digits: a string is exact */
		char num[32];
		if (co_type_is_signed(t->type))
			snprintf(num, sizeof num, "%" PRId64, le_int(data, t->size));
		else
			snprintf(num, sizeof num, "%" PRIu64, le_uint(data, t->size));
		cJSON_AddStringToObject(o, "value", num);
	} else if (co_type_is_signed(t->type)) {
		cJSON_AddNumberToObject(o, "value", (double)le_int(data, t->size));
	} else {
		cJSON_AddNumberToObject(o, "value", (double)le_uint(data, t->size));
	}
}

/* ---- raw filters, lines ---------------------------------------------------- */

static int parse_can_id(const char *s, size_t n, uint32_t *id, bool *ext)
{
	if (n == 0 || n > 8)
		return -1;
	for (size_t i = 0; i < n; i++)
		if (!isxdigit((unsigned char)s[i]))
			return -1;
	char buf[9];
	memcpy(buf, s, n);
	buf[n] = '\0';
	*id = (uint32_t)strtoul(buf, NULL, 16);
	/* can-utils convention: 3 hex digits = 11-bit, 8 = 29-bit */
	*ext = n == 8;
	if (!*ext && n > 3)
		return -1;
	if (*ext ? *id > 0x1FFFFFFFu : *id > 0x7FFu)
		return -1;
	return 0;
}

int ctl_parse_raw_filter(ctl *c, const char *s, mbx_raw_filter *f)
{
	const char *slash = strchr(s, '/');
	size_t n = slash ? (size_t)(slash - s) : strlen(s);
	uint32_t id, mask;
	bool ext, mext;
	if (parse_can_id(s, n, &id, &ext) < 0)
		goto bad;
	if (slash) {
		if (parse_can_id(slash + 1, strlen(slash + 1), &mask, &mext) < 0)
			goto bad;
	} else {
		mask = ext ? 0x1FFFFFFFu : 0x7FFu;
	}
	/* the EXT bit is always compared: an 11-bit filter never matches a
	 * 29-bit frame with the same low bits, and vice versa */
	f->id = id | (ext ? MBX_RAW_EXT : 0);
	f->mask = mask | MBX_RAW_EXT;
	return 0;
bad:
	ctl_usage_error(c,
			"filter '%s': ID[/MASK] in hex, 1..3 digits = 11-bit, 8 digits = 29-bit "
			"(e.g. 181, 700/780, 18FF0001)",
			s);
	return -1;
}

int ctl_count_lines(ctl *c)
{
	int n = 0;
	for (unsigned line = 0; line < MBX_LINES_MAX; line++) {
		char name[MBX_QNAME_MAX];
		if (mbx_queue_name(name, sizeof name, c->instance, line) < 0)
			break;
		mqd_t q = mq_open(name, O_WRONLY | O_NONBLOCK | O_CLOEXEC);
		if (q == (mqd_t)-1 && errno == ENOENT)
			break;
		if (q != (mqd_t)-1)
			mq_close(q);
		n++;
	}
	if (n == 0) {
		char name[MBX_QNAME_MAX];
		mbx_queue_name(name, sizeof name, c->instance, 0);
		fprintf(stderr,
			"cogwctl: no daemon for mailbox instance '%s' (queue %s does not exist; is "
			"cogwd running?)\n",
			c->instance, name);
		return -CTL_EXIT_NO_DAEMON;
	}
	return n;
}

void ctl_rpdo_fault_text(uint8_t faults, const char *sep, bool with_emcy, char *buf, size_t len)
{
	static const struct {
		const char *name;
		const char *emcy;
	} kinds[] = { { "deadline missed", " (8250h)" },
		      { "short", " (8210h)" },
		      { "long", " (8220h)" } };
	size_t off = 0;
	buf[0] = 0;
	for (unsigned k = 0; k < sizeof kinds / sizeof kinds[0]; k++)
		if ((faults & (1u << k)) && off < len)
			off += (size_t)snprintf(buf + off, len - off, "%s%s%s", off ? sep : "",
						kinds[k].name, with_emcy ? kinds[k].emcy : "");
}

/* A command's --help, with what every command shares. */
int ctl_print_help(const ctl_cmd *cmd)
{
	fputs(cmd->help, stdout);
	fputs("\nGlobal options: --instance NAME, --timeout MS, --json, --help.\n"
	      "Exit status: 0 ok, 1 refused/abort, 2 usage, 3 daemon not reachable, 4 timeout.\n",
	      stdout);
	return CTL_EXIT_OK;
}

int ctl_each_line(ctl *c, const char *const *pos, int n_pos,
		  int (*one)(ctl *c, cogw *h, unsigned line, cJSON *arr))
{
	unsigned lines[MBX_LINES_MAX];
	int n_lines = n_pos, ex = 0, rc;
	for (int i = 0; i < n_pos; i++)
		if (ctl_arg_line(c, pos[i], &lines[i]) < 0)
			return CTL_EXIT_USAGE;
	if (n_lines == 0) {
		int n = ctl_count_lines(c);
		if (n < 0)
			return -n;
		for (int i = 0; i < n; i++)
			lines[i] = (unsigned)i;
		n_lines = n;
	}
	cogw *h = ctl_handle(c, &ex);
	if (!h)
		return ex;
	cJSON *arr = c->json ? cJSON_CreateArray() : NULL;
	for (int i = 0; i < n_lines; i++) {
		if (i && !c->json)
			printf("\n");
		rc = one(c, h, lines[i], arr);
		if (rc) {
			cJSON_Delete(arr);
			return rc;
		}
	}
	if (c->json) {
		cJSON *o = cJSON_CreateObject();
		cJSON_AddBoolToObject(o, "ok", true);
		cJSON_AddStringToObject(o, "instance", c->instance);
		cJSON_AddItemToObject(o, "lines", arr);
		ctl_json_print(o);
	}
	return 0;
}

int ctl_run_lines(ctl *c, int argc, char **argv, const ctl_cmd *cmd,
		  int (*one)(ctl *c, cogw *h, unsigned line, cJSON *arr))
{
	const char *pos[MBX_LINES_MAX];
	int n_pos;
	int rc = ctl_parse(c, argc, argv, NULL, pos, MBX_LINES_MAX, &n_pos);
	if (rc)
		return rc;
	if (c->help)
		return ctl_print_help(cmd);
	return ctl_each_line(c, pos, n_pos, one);
}
