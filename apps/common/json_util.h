/* SPDX-License-Identifier: MIT */
/*
 * apps/common/json_util.h - strict cJSON helpers shared by cogwd's
 * configuration (config.c), the OD builder (json_od.c) and the device
 * simulator's JSON device files.
 *
 * Errors are written as "path: reason" (no source prefix; the caller adds
 * "file: "), e.g. "lines[1].node_id: 200 is out of range 1..127". Paths
 * use JSON notation: key names joined with '.', array positions in [n].
 * The readers take their path and error buffer as one json_at.
 * All functions return 0 or -EINVAL (the message is in err).
 * No global state; any thread.
 */
#ifndef COGW_APPS_JSON_UTIL_H
#define COGW_APPS_JSON_UTIL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include <cjson/cJSON.h>

#define JSON_PATH_MAX 160

/* Longest integer a JSON number may carry exactly (2^53): larger values
 * must be written as strings ("0xFFFFFFFFFFFFFFFF", "-9007199254740993"). */
#define JSON_EXACT_INT_MAX 9007199254740992.0

/* Parse text; on invalid JSON the reason is "line L column C: invalid
 * JSON" (1-based, counted in bytes) and *out is NULL. */
int json_util_parse(const char *text, cJSON **out, char *err, size_t errlen);

/* "path.key" / "path[i]" into buf (truncated safely). */
void json_util_path_key(char *buf, size_t n, const char *path, const char *key);
void json_util_path_index(char *buf, size_t n, const char *path, size_t i);

/* Write "path: reason" (printf-style reason). Always returns -EINVAL. */
int json_util_fail(char *err, size_t errlen, const char *path, const char *fmt, ...)
	__attribute__((format(printf, 4, 5)));

/* A short rendering of a value for messages: 200, 1.5, "abc", true, an
 * object, an array. */
void json_util_repr(const cJSON *v, char *buf, size_t n);
/* "an integer", "a string", ... the kind of a value, for messages. */
const char *json_util_kind(const cJSON *v);

/* A JSON number of the finite REAL32/REAL64 whose exact decimal text (one
 * that reads back to the same bits) is `text`, written as it is, with
 * ".0" added when it looks like an integer: every JSON reader then takes
 * it as a floating-point number ("-0" would be the integer 0 to most,
 * losing the sign). NULL when out of memory. */
cJSON *json_util_real_number(const char *text);

/*
 * Where a reader is: the path of the value (or, for the member forms, of
 * the object whose member it reads) and the buffer its "path: reason"
 * goes to. One is set up per path and handed to every reader there:
 *
 *   const json_at at = { "lines[0]", err, errlen };
 *   rc = json_util_opt_uint(o, "node_id", &at, 1, 127, &id);
 */
typedef struct json_at {
	const char *path;
	char *err;
	size_t errlen;
} json_at;

/*
 * obj must be an object whose keys are all in `allowed` (NULL-terminated)
 * and appear once; "path.key: unknown key" (with a "did you mean" hint
 * for a near miss) or "path.key: duplicate key" otherwise.
 */
int json_util_check_object(const cJSON *obj, const json_at *at, const char *const *allowed);

/* Member lookup (exact, case-sensitive). */
const cJSON *json_util_get(const cJSON *obj, const char *key);
/* A required member: "path.key: required key is missing". */
int json_util_require(const cJSON *obj, const char *key, const json_at *at, const cJSON **out);

/*
 * Integers: a JSON number without a fraction and within +-2^53, or a
 * string holding a decimal ("-12"), hexadecimal ("0x1A00") or octal
 * ("0660", leading 0) integer. neg and mag give sign and magnitude, so that
 * the full INTEGER64 and UNSIGNED64 ranges are representable.
 */
int json_util_int(const cJSON *v, const json_at *at, bool *neg, uint64_t *mag);
/* Range-checked forms, min and max included. hex: print the range in hex
 * (indexes, COB-IDs). */
int json_util_uint(const cJSON *v, const json_at *at, uint64_t min, uint64_t max, bool hex,
		   uint64_t *out);
int json_util_sint(const cJSON *v, const json_at *at, int64_t min, int64_t max, int64_t *out);
/* A JSON number (any, finite). */
int json_util_real(const cJSON *v, const json_at *at, double *out);
int json_util_bool(const cJSON *v, const json_at *at, bool *out);
/* A string of 1..cap-1 bytes (min_len 0 allows ""), copied into buf. */
int json_util_string(const cJSON *v, const json_at *at, size_t min_len, char *buf, size_t cap);

/* Optional member forms: obj's member key (at "path.key"); absent leaves
 * *out unchanged. */
int json_util_opt_uint(const cJSON *obj, const char *key, const json_at *at, uint64_t min,
		       uint64_t max, uint64_t *out);
int json_util_opt_sint(const cJSON *obj, const char *key, const json_at *at, int64_t min,
		       int64_t max, int64_t *out);
int json_util_opt_bool(const cJSON *obj, const char *key, const json_at *at, bool *out);
int json_util_opt_string(const cJSON *obj, const char *key, const json_at *at, size_t min_len,
			 char *buf, size_t cap);

/* json_util_opt_uint into an unsigned int (max must fit one). */
int json_util_opt_unsigned(const cJSON *obj, const char *key, const json_at *at, uint64_t min,
			   uint64_t max, unsigned *out);

/* A configuration text: parse json, hand the tree to load(ctx, root, ...),
 * and on failure write "source: path: reason" into err. Returns load's
 * result (or -EINVAL for invalid JSON). */
int json_util_load_text(const char *json, const char *source,
			int (*load)(void *ctx, const cJSON *root, char *err, size_t errlen),
			void *ctx, char *err, size_t errlen);
/* The same for a file of at most max bytes, read by cogw_file_read
 * (apps/common/file_read.h): -ENOENT when it does not exist, -EIO when it
 * cannot be read, else as json_util_load_text. */
int json_util_load_file(const char *path, size_t max,
			int (*load)(void *ctx, const cJSON *root, char *err, size_t errlen),
			void *ctx, char *err, size_t errlen);

/* Hex bytes "01 02 0a" / "01020A" (spaces allowed between byte pairs).
 * *len = bytes decoded; "path: ..." if odd, not hex, or longer than cap. */
int json_util_hex(const cJSON *v, const json_at *at, uint8_t *buf, size_t cap, size_t *len);
/* Bytes the hex string in v decodes to, or -1 if it is not valid hex. */
long json_util_hex_len(const cJSON *v);

#endif /* COGW_APPS_JSON_UTIL_H */
