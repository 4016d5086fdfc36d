/* SPDX-License-Identifier: MIT */
/*
 * apps/common/eds_pdo.h - what a device file (CiA 306 EDS/DCF) says of the
 * device's PDOs: the valid TPDOs and RPDOs (CiA 301 §7.5.2.35-38, records
 * 1400h..1BFFh; ParameterValue, else DefaultValue, $NODEID resolved) with
 * the mapped objects' data types and access from the same file, in the
 * form the manager's table of learned layouts keeps (core/pdo_layout.h),
 * and the type list of the file's objects (co_pdo_layout_type) that types
 * a scanned layout. Reference: docs/config.md "PDO layouts".
 *
 * Built from the sub-objects apps/common/eds.c reports (eds_options
 * .on_entry), so a file is read once, by the one reader, with its rules:
 *
 *   eds_pdo_reader r = { .overrides = { list, n } };
 *   opts.on_entry = eds_pdo_reader_on_entry; opts.entry_arg = &r;
 *   eds_convert_opts(..., &opts, &result);
 *   eds_pdo_reader_finish(&r, file, &layout, &types, err, errlen);
 *   eds_pdo_reader_free(&r);
 *
 * Errors: -EINVAL with "file: reason" (a valid PDO whose mapping cannot be
 * used: more than 64 bits, an entry without a value, an object mapped
 * with a length other than its type's), -ENOMEM. Main thread, build time
 * only (allocates).
 */
#ifndef COGW_APPS_EDS_PDO_H
#define COGW_APPS_EDS_PDO_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "apps/common/eds.h"
#include "core/pdo_layout.h"

/* A list of object types, sorted by index and sub. */
typedef struct eds_pdo_types {
	co_pdo_layout_type *list;
	size_t n;
} eds_pdo_types;

/* The sub-objects collected while a file is read. */
typedef struct eds_pdo_reader {
	/* Given by the caller: the configuration's types, which win over the
	 * file's (sorted; the caller's memory, not freed by the reader). */
	eds_pdo_types overrides;
	co_pdo_layout_type *obj; /* every typed sub-object, in file order */
	uint32_t *value;         /* obj[i]'s value (up to 4 bytes, LE) */
	bool *has_value;
	size_t n, cap;
	bool out_of_memory;
} eds_pdo_reader;

/* The device's valid PDOs as the file gives them (malloc'd). */
typedef struct eds_pdo_file {
	co_pdo_layout_pdo *pdo[2]; /* [co_pdo_dir]: CO_PDO_TX = the device's TPDOs */
	uint16_t n[2];
} eds_pdo_file;

/* An eds_entry_fn: collects one sub-object into the reader `arg`. */
void eds_pdo_reader_on_entry(void *arg, const eds_entry *e);

/* The layout of `file` (the one read) into *layout (may be NULL: types
 * only) and its type list into *types (malloc'd, sorted; may be NULL),
 * r->overrides winning over the file. */
int eds_pdo_reader_finish(eds_pdo_reader *r, const char *file, eds_pdo_file *layout,
			  eds_pdo_types *types, char *err, size_t errlen);
void eds_pdo_reader_free(eds_pdo_reader *r); /* accepts zeroed */
void eds_pdo_file_free(eds_pdo_file *f);     /* accepts zeroed */

/* Sort a type list by index and sub; false when an object is in it twice
 * (*dup = that entry). */
bool eds_pdo_types_sort(co_pdo_layout_type *list, size_t n, const co_pdo_layout_type **dup);

#endif /* COGW_APPS_EDS_PDO_H */
