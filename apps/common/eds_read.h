/* SPDX-License-Identifier: MIT */
/*
 * apps/common/eds_read.h - what the passes of the CiA 306 EDS/DCF reader
 * share (eds.c and the eds_*.c below it): the sections and keys of the
 * file, the values collected, the reader's context, and each pass's entry
 * points. Internal to apps/common; the contract is in eds.h.
 *
 * Every function that can refuse the file returns -EINVAL with
 * "file:line: reason" in c->msg (eds_fail), or -ENOMEM.
 */
#ifndef COGW_APPS_EDS_READ_H
#define COGW_APPS_EDS_READ_H

#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "apps/common/eds.h"
#include "core/od.h"

enum sec_kind {
	SEC_OTHER = 0, /* FileInfo, DeviceInfo, object lists, ... */
	SEC_OBJ,       /* [XXXX] */
	SEC_SUB,       /* [XXXXsubY] */
	SEC_NAME,      /* [XXXXName] (CompactSubObj names) */
	SEC_VALUE,     /* [XXXXValue] (CompactSubObj values in a DCF) */
	SEC_DENOT,     /* [XXXXDenotation] */
	SEC_LINKS,     /* [XXXXObjectLinks] */
};

typedef struct ini_key {
	const char *key;
	const char *val;
	unsigned line;
} ini_key;

typedef struct ini_sec {
	const char *name;
	unsigned line;
	enum sec_kind kind;
	uint16_t index;
	uint8_t sub;
	ini_key *keys;
	size_t nkeys, cap;
} ini_sec;

/* One value to write. */
typedef struct out_var {
	uint16_t index;
	uint8_t sub;
	unsigned line; /* line of the value */
	uint8_t *data;
	uint32_t size;
} out_var;

typedef struct eds_ctx {
	const char *file;
	char *text;
	ini_sec *secs;
	size_t nsecs, cap;
	ini_sec **sorted;
	uint8_t node_id;
	out_var *vars;
	size_t nvars, vcap;
	out_var *emit; /* output order (shallow copies of vars) */
	size_t nemit, ecap;
	eds_stats st;
	bool strict;
	bool node_id_missing; /* a refusal for want of an input, not a file fault */
	eds_warning_fn on_warning;
	void *warning_arg;
	eds_entry_fn on_entry;
	void *entry_arg;
	char msg[512]; /* the refusal, "file:line: reason", copied to eds_result.err */
} eds_ctx;

typedef struct num_val {
	bool neg;
	uint64_t mag;
	bool pattern;
} num_val;

/* A sub-object as read from one section (or from a compact object). */
typedef struct var_spec {
	uint16_t index;
	uint8_t sub;
	const ini_sec *sec;   /* where DataType/AccessType/limits live */
	const ini_key *value; /* ParameterValue or DefaultValue; NULL = none */
	const char *where;    /* section name for messages */
} var_spec;

/* ---- messages, growing arrays, text (eds_base.c) ---- */

/* A refusal: "file:line: reason" into c->msg, -EINVAL. */
int eds_fail(eds_ctx *c, unsigned line, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
/* A warning: counted, the first kept in the stats, handed to on_warning. */
void eds_warn(eds_ctx *c, unsigned line, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));
/* Inconsistent but usable: a warning, or a refusal when reading strictly. */
int eds_tolerate(eds_ctx *c, unsigned line, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));
/* A refusal (rc, reason in c->msg) turned into a warning that says what
 * is left out instead - when reading leniently. */
int eds_tolerate_failure(eds_ctx *c, int rc, const char *left_out);
/* Room for need elements of elem bytes in *p (capacity *cap). */
int eds_grow(void **p, size_t *cap, size_t need, size_t elem);
/* s..end without the blanks around it, terminated. */
char *eds_trim(char *s, char *end);
/* A hex digit's value, -1 for anything else. */
int eds_hexval(int ch);

/* ---- passes 1 and 2: INI text, sorted sections (eds_ini.c) ---- */

/* Pass 1: c->text to sections and keys, every line numbered. */
int eds_parse_ini(eds_ctx *c, size_t len);
/* Pass 2: c->sorted, duplicates side by side (a refusal). */
int eds_sort_sections(eds_ctx *c);
/* The section of that kind, index and sub (NULL: none). */
ini_sec *eds_find_sec(const eds_ctx *c, enum sec_kind kind, uint16_t index, uint8_t sub,
		      const char *name);
/* Position of the first sorted section at or after (kind, index, 0). */
size_t eds_lower_bound(const eds_ctx *c, enum sec_kind kind, uint16_t index);
/* Key of a section by name, case-insensitive (NULL: none). */
const ini_key *eds_get_key(const ini_sec *s, const char *key);

/* ---- numbers (eds_num.c) ---- */

/* An integer expression: literal, $NODEID, $NODEID+literal, literal+$NODEID. */
int eds_parse_int_expr(eds_ctx *c, const ini_key *k, num_val *out);
/* Numeric value of key k as a bit pattern of type t. */
int eds_parse_num(eds_ctx *c, const ini_key *k, co_type t, uint64_t *bits);
/* a <=> b as values of type t. */
int eds_num_cmp(co_type t, uint64_t a, uint64_t b);

/* ---- one value: type, access, encoding, limits (eds_value.c) ---- */

/* CiA 306 AccessType to the CO_ACC_* flags (core/od.h); "rw" may also be
 * mapped, as the file does not say otherwise. */
int eds_parse_access(eds_ctx *c, const ini_key *k, uint8_t *access);
/* An unsigned key in 0..max. */
int eds_parse_uint_key(eds_ctx *c, const ini_key *k, uint64_t max, uint64_t *out);
/* A section's DataType. */
int eds_parse_type(eds_ctx *c, const ini_sec *s, co_type *t);
/* A value to write, collected (data is taken over). */
int eds_add_var(eds_ctx *c, uint16_t index, uint8_t sub, unsigned line, uint8_t *data,
		uint32_t size);
/* One sub-object's value checked, reported, and collected when written. */
int eds_do_var(eds_ctx *c, const var_spec *v, co_type t, uint8_t access);

/* ---- pass 3: objects and object lists (eds_objects.c) ---- */

/* Pass 3 for one [XXXX] section and what belongs to it. */
int eds_do_object(eds_ctx *c, const ini_sec *o);
/* [XXXXObjectLinks]: ObjectLinks=n, 1..n = indexes of described objects. */
int eds_do_links(eds_ctx *c, const ini_sec *s);
/* [MandatoryObjects] etc.: SupportedObjects=n, 1..n = indexes. Vendor
 * files get the count wrong and list objects they do not describe;
 * nothing is lost, so these are warnings also when reading strictly. */
int eds_do_list(eds_ctx *c, const char *name);
/* Sub-sections, names and values without their object. */
int eds_check_orphans(eds_ctx *c);
/* The node-ID of [DeviceComissioning] NodeID, when it is one. */
int eds_node_from_file(eds_ctx *c);

/* ---- download order and the concise DCF (eds_emit.c) ---- */

/* c->emit: the values in download order. */
int eds_order_vars(eds_ctx *c);
/* c->emit as a concise DCF (malloc'ed). */
int eds_write_cdcf(eds_ctx *c, uint8_t **out, size_t *out_len);

#endif /* COGW_APPS_EDS_READ_H */
