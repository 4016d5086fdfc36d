/* SPDX-License-Identifier: MIT */
/*
 * apps/common/json_od.h - building an object dictionary from JSON: object
 * definitions ("objects") and initial values ("values"). Used by cogwd's
 * configuration for each line's own OD and by the device simulator (cosim)
 * for its JSON device files. The JSON shapes are documented in
 * docs/config.md ("objects", "values").
 *
 * Errors: -EINVAL with "path: reason" in err, where path starts with
 * path_prefix, e.g. "lines[0].objects[2].default: 2000 is above max 1000".
 * -ENOMEM for allocation failures. On error the OD may hold some of the
 * new objects: callers throw it away (a half-built OD is never used).
 *
 * Build time only (allocates); no global state.
 */
#ifndef COGW_APPS_JSON_OD_H
#define COGW_APPS_JSON_OD_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include <cjson/cJSON.h>

#include "core/od.h"

/* Largest string/domain capacity ("max_size") a JSON object may ask for. */
#define JSON_OD_MAX_SIZE (16u * 1024u * 1024u)

/*
 * Add every object of the JSON array `objects` (VAR, ARRAY or RECORD; see
 * docs/config.md). An index that already exists in the OD (a standard
 * object, or one defined twice) is refused: initial values of existing
 * objects belong in "values".
 */
int json_od_add_objects(co_od *od, const cJSON *objects, const char *path_prefix, char *err,
			size_t errlen);

/*
 * Apply the JSON array `values`: [{"index": .., "sub": .., "value": ..}].
 * Each value is checked against the entry's type, size and limits (the
 * checks an SDO write gets, co_od_check_value) and becomes the entry's
 * default and current value, so that an NMT reset returns to it. Access
 * rights are not checked: the configuration may set read-only and const
 * objects (1008h, 1018h, ...).
 */
int json_od_apply_values(co_od *od, const cJSON *values, const char *path_prefix, char *err,
			 size_t errlen);

/* Where an encoded value goes: at most cap bytes at buf; its size into len. */
typedef struct json_od_buf {
	uint8_t *buf;
	uint32_t cap;
	uint32_t len;
} json_od_buf;

/*
 * Encode one JSON value as the wire bytes of type t (see docs/config.md,
 * "Values by type") into out. Numbers are range-checked against the type;
 * strings against out->cap.
 */
int json_od_parse_value(const cJSON *v, co_type t, const char *path, json_od_buf *out, char *err,
			size_t errlen);

/* An index 0x1000..0xFFFF: a number or a string "0x1A00". */
int json_od_parse_index(const cJSON *v, const char *path, uint16_t *out, char *err, size_t errlen);

/* UTF-8 text (NUL-terminated) to UTF-16LE, the wire form of
 * UNICODE_STRING. out NULL: only count. Returns the byte length, -1 for
 * invalid UTF-8 (or surrogates), -2 if it does not fit cap. */
long json_od_utf8_to_utf16le(const char *s, uint8_t *out, uint32_t cap);

/* "UNSIGNED16" -> CO_T_UNSIGNED16 (exact, upper case, as co_type_to_string
 * prints). false if unknown. */
bool json_od_type_from_string(const char *s, co_type *t);

/* "ro", "wo", "rw", "rwr", "rww", "const" -> enum co_access. false if
 * unknown. */
bool json_od_access_from_string(const char *s, uint16_t *acc);

#endif /* COGW_APPS_JSON_OD_H */
