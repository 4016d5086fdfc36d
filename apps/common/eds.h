/* SPDX-License-Identifier: MIT */
/*
 * apps/common/eds.h - CiA 306 electronic data sheets (EDS) and device
 * configuration files (DCF) converted to a concise DCF (core/cdcf.h), the
 * form a manager downloads into a slave (1F22h). Used by cogwd for a
 * node's "config" and by `cogwctl dcf`, so both give the same result.
 *
 * How files are read (docs/config.md, "DCF and EDS files"): the CiA 306
 * INI form - [section], key=value, ';' comment lines, case-insensitive
 * section names and keys; object sections [XXXX], sub-objects [XXXXsubY],
 * CompactSubObj with [XXXXName]/[XXXXValue], [XXXXObjectLinks], the object
 * lists and [DeviceComissioning] NodeID. Values: ParameterValue (a DCF's
 * configured value) before DefaultValue; integers in decimal, 0x hex or
 * leading-0 octal with $NODEID expressions ("$NODEID+0x180"), hex/octal
 * as a signed type's two's complement; REAL32/REAL64 in decimal or as 0x
 * IEEE 754 bits; VISIBLE_STRING as text, UNICODE_STRING as UTF-8 (sent as
 * UTF-16LE), OCTET_STRING and DOMAIN as hex digits.
 *
 * Like the widely used tools, the reader takes what real device files
 * contain: what is inconsistent but usable is a warning ("file:line:
 * reason", eds_stats and the on_warning callback) and the file is used;
 * only what cannot be used is refused. eds_options.strict refuses every
 * one of those warnings except the object-list ones (the reader's rules
 * before it read leniently). The full list is in docs/config.md.
 *
 * What is written: every value that a configuration can write - entries
 * whose AccessType is wo, rw, rwr or rww and that have a non-empty value -
 * in object order, except the objects that are commands rather than
 * configuration (1003h, 1010h, 1011h, 1021h, 1023h, 1F25h, 1F50h, 1F51h).
 * PDO parameters follow the CiA 301 re-mapping procedure: COB-ID with bit
 * 31 set (PDO invalid), the other communication parameters, mapping sub0
 * = 0, mapping entries 1..N, mapping sub0 = N, then the final COB-ID.
 *
 * Errors: -EINVAL with "file:line: reason" in eds_result.err (line 0 for
 * problems of the whole file), -ENOMEM, or -errno of the file for
 * eds_convert_file.
 * No global state; any thread; allocates (not for a real-time path).
 */
#ifndef COGW_APPS_EDS_H
#define COGW_APPS_EDS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* Largest EDS/DCF file accepted (real device files are well below 1 MiB). */
#define EDS_FILE_MAX (16u * 1024u * 1024u)

typedef struct eds_stats {
	unsigned objects; /* object sections read */
	unsigned values;  /* values parsed (all access types) */
	unsigned entries; /* entries in the concise DCF */
	unsigned skipped; /* writable sub-objects without a (usable) value */
	uint8_t node_id;  /* node id the $NODEID expressions used (0 = none) */
	/* Inconsistent but usable things (a SubNumber that disagrees with
	 * the sub-object sections, a default value that cannot be used, an
	 * object list naming an object the file does not describe, ...):
	 * real device files have them, so they are reported, not refused. */
	unsigned warnings;
	char first_warning[200]; /* "file:line: reason" of the first one */
} eds_stats;

/* Called with every warning, "file:line: reason" (no newline). */
typedef void (*eds_warning_fn)(void *arg, const char *warning);

/* One sub-object as the file describes it (eds_options.on_entry): its
 * DataType, AccessType as CO_ACC_* flags (core/od.h) and its value
 * (ParameterValue, else DefaultValue, $NODEID resolved) as the bytes it is
 * sent as, NULL when it has none or none that can be used. Every entry of
 * a usable type is reported, writable or not; the pointers are valid
 * during the call only. */
typedef struct eds_entry {
	uint16_t index;
	uint8_t sub;
	uint16_t type; /* co_type */
	uint8_t access;
	const uint8_t *value;
	uint32_t size;
	unsigned line; /* of the value, else of the section */
} eds_entry;

typedef void (*eds_entry_fn)(void *arg, const eds_entry *e);

typedef struct eds_options {
	uint8_t node_id;           /* what $NODEID stands for, 1..127; 0 = the file's NodeID */
	bool strict;               /* refuse what is otherwise a warning (see above) */
	eds_warning_fn on_warning; /* NULL: only counted in eds_stats */
	void *warning_arg;
	eds_entry_fn on_entry; /* NULL: sub-objects not reported */
	void *entry_arg;
} eds_options;

/* What a conversion gives back. */
typedef struct eds_result {
	uint8_t *cdcf; /* the concise DCF (malloc'd, the caller frees it; also
			* when it has no entries), NULL when refused */
	size_t len;
	eds_stats stats; /* also when the file was refused: its warnings */
	char err[512];   /* why it was refused ("" when it was not) */
} eds_result;

/*
 * Convert the text of an EDS/DCF (len bytes, need not be NUL-terminated;
 * `file` names it in errors) into a concise DCF in res. node_id 1..127 is
 * what $NODEID stands for; 0 = take [DeviceComissioning] NodeID, and a
 * $NODEID with no node id at all is an error.
 */
int eds_convert(const char *text, size_t len, const char *file, uint8_t node_id, eds_result *res);

/* Read a file (at most EDS_FILE_MAX bytes) and eds_convert it. */
int eds_convert_file(const char *path, uint8_t node_id, eds_result *res);

/* The same with options (eds_convert reads leniently, without a callback). */
int eds_convert_opts(const char *text, size_t len, const char *file, const eds_options *opts,
		     eds_result *res);
int eds_convert_file_opts(const char *path, const eds_options *opts, eds_result *res);

#endif /* COGW_APPS_EDS_H */
