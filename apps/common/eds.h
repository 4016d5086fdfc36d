/* SPDX-License-Identifier: MIT */
/*
 * apps/common/eds.h - CiA 306 electronic data sheets (EDS) and device
 * configuration files (DCF) converted to a concise DCF (core/cdcf.h), the
 * form a manager downloads into a slave (1F22h). Used by cogwd for a
 * node's "config" and by `cogwctl dcf`, so both give the same result.
 *
 * What is read (docs/config.md, "DCF and EDS files"):
 * - INI syntax: [section], key=value, ';' comments; keys and section names
 *   are case-insensitive. Duplicate sections or keys are errors.
 * - Object sections [XXXX], sub-objects [XXXXsubY], ObjectType (VAR,
 *   ARRAY, RECORD, DOMAIN, DEFTYPE, DEFSTRUCT), DataType (CiA 301 basic
 *   types), AccessType (ro, wo, rw, rwr, rww, const), SubNumber,
 *   CompactSubObj with [XXXXName] and [XXXXValue], [XXXXObjectLinks],
 *   LowLimit/HighLimit, the object lists [MandatoryObjects],
 *   [OptionalObjects], [ManufacturerObjects], and [DeviceComissioning]
 *   NodeID.
 * - Values: ParameterValue (a DCF's configured value) is preferred over
 *   DefaultValue. Integers in decimal, hex (0x..) or octal (leading 0),
 *   with $NODEID expressions: "$NODEID", "$NODEID+0x180", "0x180+$NODEID".
 *   Hex and octal literals of signed types may be given as the two's
 *   complement bit pattern (0xFFFFFFFF = -1 for INTEGER32). REAL32/REAL64
 *   as decimal floating point, or 0x.. for the IEEE 754 bit pattern.
 *   VISIBLE_STRING as text, UNICODE_STRING as UTF-8 text (sent as
 *   UTF-16LE), OCTET_STRING and DOMAIN as hex digits.
 *
 * What is written: every value that a configuration can write - entries
 * whose AccessType is wo, rw, rwr or rww and that have a non-empty value -
 * in object order, except the objects that are commands rather than
 * configuration (1003h, 1010h, 1011h, 1021h, 1023h, 1F25h, 1F50h, 1F51h).
 * PDO parameters follow the CiA 301 re-mapping procedure: COB-ID with bit
 * 31 set (PDO invalid), the other communication parameters, mapping sub0
 * = 0, mapping entries 1..N, mapping sub0 = N, then the final COB-ID.
 *
 * Errors: -EINVAL with "file:line: reason" in err (line 0 for problems of
 * the whole file), -ENOMEM, or -errno of the file for eds_load_file.
 * No global state; any thread; allocates (not for a real-time path).
 */
#ifndef COGW_APPS_EDS_H
#define COGW_APPS_EDS_H

#include <stddef.h>
#include <stdint.h>

/* Largest EDS/DCF file accepted (real device files are well below 1 MiB). */
#define EDS_FILE_MAX (16u * 1024u * 1024u)

typedef struct eds_stats {
	unsigned objects; /* object sections read */
	unsigned values;  /* values parsed (all access types) */
	unsigned entries; /* entries in the concise DCF */
	unsigned skipped; /* writable sub-objects without a value */
	uint8_t node_id;  /* node id the $NODEID expressions used (0 = none) */
	/* Inconsistencies that lose nothing (an object list naming an object
	 * the file does not describe, a wrong SupportedObjects count): real
	 * device files have them, so they are reported, not refused. */
	unsigned warnings;
	char first_warning[200]; /* "file:line: reason" of the first one */
} eds_stats;

/*
 * Convert the text of an EDS/DCF (len bytes, need not be NUL-terminated;
 * `file` names it in errors) into a concise DCF in *out (malloc'd, caller
 * frees; also when it has no entries). node_id 1..127 is what $NODEID
 * stands for; 0 = take [DeviceComissioning] NodeID, and a $NODEID with no
 * node id at all is an error. stats may be NULL.
 */
int eds_convert(const char *text, size_t len, const char *file, uint8_t node_id, uint8_t **out,
		size_t *out_len, eds_stats *stats, char *err, size_t errlen);

/* Read a file (at most EDS_FILE_MAX bytes) and eds_convert it. */
int eds_convert_file(const char *path, uint8_t node_id, uint8_t **out, size_t *out_len,
		     eds_stats *stats, char *err, size_t errlen);

#endif /* COGW_APPS_EDS_H */
