/* SPDX-License-Identifier: MIT */
/*
 * apps/common/node_config.h - where the configuration of one slave node
 * comes from (the "config" member of a node in cogw.json), turned into the
 * concise DCF that the CiA 302-3 configuration manager downloads (1F22h).
 * Reference: docs/config.md, "Node configuration".
 *
 *   "config": { "entries": [ {"index": "0x1017", "sub": 0,
 *                              "type": "UNSIGNED16", "value": 500}, ... ] }
 *   "config": { "dcf": "transducer.dcf" }      CiA 306 DCF or EDS
 *   "config": { "concise": "transducer.cdc" }  binary concise DCF
 * plus, for any of them:
 *   "store": true          write "save" to 1010h:1 after a download
 *   "date": D, "time": T   expected configuration date/time (1F26h/1F27h:
 *                          days since 1984-01-01, ms after midnight); the
 *                          download is skipped while the slave's 1020h:1/2
 *                          hold them, and they are written to 1020h after
 *                          a download
 *
 * Relative file names are taken from base_dir (the directory of the
 * configuration file); $NODEID in a DCF/EDS is the node's id.
 *
 * Errors: -EINVAL with "path: reason" in err, where path is the JSON path
 * (e.g. "lines[0].nodes[2].config.entries[3].value: 300 is above ...") and
 * a file's errors add the file and line ("...config.dcf: x.dcf:12: ...").
 * -ENOMEM. Main thread, build time only (allocates and reads files).
 */
#ifndef COGW_APPS_NODE_CONFIG_H
#define COGW_APPS_NODE_CONFIG_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include <cjson/cJSON.h>

#include "apps/common/eds_pdo.h"
#include "apps/common/file_read.h"

/* Size of a resolved file name (cogw_node_config.file, cogw_node.eds). */
#define COGW_FILE_NAME_MAX 256u

/* Largest concise DCF of one node (also the largest .cdc file read). */
#define COGW_NODE_CONFIG_MAX (1u << 20)
/* Largest value of one JSON entry (strings, domains). */
#define COGW_NODE_ENTRY_MAX 4096u

typedef enum cogw_node_config_source {
	COGW_NODE_CONFIG_NONE = 0,
	COGW_NODE_CONFIG_ENTRIES, /* "entries" in the JSON */
	COGW_NODE_CONFIG_DCF,     /* "dcf": a CiA 306 DCF/EDS file */
	COGW_NODE_CONFIG_CONCISE, /* "concise": a binary concise DCF file */
} cogw_node_config_source;

const char *cogw_node_config_source_to_string(cogw_node_config_source s);

typedef struct cogw_node_config {
	uint8_t source;                /* cogw_node_config_source */
	char file[COGW_FILE_NAME_MAX]; /* dcf/concise: the file read (resolved path) */
	uint8_t *cdcf;                 /* the concise DCF (owned, malloc'd) */
	size_t cdcf_len;
	uint32_t entries; /* entries in cdcf */
	bool store;       /* 1010h:1 "save" after a download */
	bool verify;      /* date/time given */
	uint32_t date;    /* 1F26h: days since 1984-01-01 */
	uint32_t time;    /* 1F27h: ms after midnight */
} cogw_node_config;

/* A file compiled into the program (see cogw_default_files). */
typedef struct cogw_embedded_file {
	const char *name; /* as the configuration names it, e.g. "transducer.dcf" */
	const char *data; /* NUL-terminated copy of the bytes */
	size_t len;
} cogw_embedded_file;

/* What a load reads its files from and where it reports: files is where
 * a "dcf" file name is looked up first (the embedded default's own files),
 * NULL for a configuration read from disk; names are relative to base_dir
 * (NULL or "" = the working directory). read: the files the configuration
 * has loaded so far; a file named again is not read again, and the file
 * and the node's concise DCF are counted against read->limit (-EINVAL with
 * "path: file: ... do not fit" when they do not fit). Errors go to err. */
typedef struct cogw_load {
	const char *base_dir;
	const cogw_embedded_file *files;
	cogw_file_set *read;
	char *err;
	size_t errlen;
} cogw_load;

/* The device a node's file describes: its node-ID (for $NODEID) and the
 * reader of its sub-objects (eds_pdo.h; NULL: not wanted). */
typedef struct cogw_device_ref {
	uint8_t node_id;
	eds_pdo_reader *pdo;
} cogw_device_ref;

/* A node's "config" (v, at path) into out; a "dcf" file's sub-objects go
 * to dev->pdo: the configured device's PDO layout. */
int cogw_node_config_parse(const cJSON *v, const char *path, cogw_device_ref dev,
			   const cogw_load *ld, cogw_node_config *out);
/* A node's "eds" (v, at path): the CiA 306 file describing the device,
 * read and checked like a "dcf" (nothing of it is downloaded), its
 * sub-objects into dev->pdo; the resolved name into file
 * (COGW_FILE_NAME_MAX bytes). Errors as above. */
int cogw_device_file_read(const cJSON *v, const char *path, cogw_device_ref dev,
			  const cogw_load *ld, char *file);
void cogw_node_config_free(cogw_node_config *nc); /* accepts zeroed */
/* Same source and bytes (what a reload compares). */
bool cogw_node_config_equal(const cogw_node_config *a, const cogw_node_config *b);

/* Read a binary concise DCF file and check it (core/cdcf.h). Errors:
 * "file: entry 3 (1800:02) at byte 25: ..." in err, -EINVAL, -ENOENT,
 * -EIO, -EFBIG, -ENOMEM. */
int cogw_cdcf_load_file(const char *file, uint8_t **out, size_t *len, char *err, size_t errlen);

#endif /* COGW_APPS_NODE_CONFIG_H */
