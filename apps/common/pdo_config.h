/* SPDX-License-Identifier: MIT */
/*
 * apps/common/pdo_config.h - the configuration of what a line learns of
 * its slaves' PDOs (docs/config.md "PDO layouts"):
 *
 *   lines[].pdo            "off" | "learn" | "auto" (default "off")
 *   lines[].pdo_scan_max   PDOs per direction scanned and kept (1..512, 8)
 *   nodes[].pdo            as the line's, which it inherits
 *   nodes[].eds            the device's EDS/DCF when nothing is downloaded
 *   nodes[].types          {"6401:1": "INTEGER16", ...}: data types of
 *                          objects, over the file's
 *
 * A node's layout comes from a file - its config.dcf (the configured
 * device), or its eds when it has no "config" - and is then never scanned;
 * with "eds" and a "config" of entries or a concise DCF the download may
 * change the PDOs, so the layout is scanned and the file only types it.
 *
 * Errors: -EINVAL with "path: reason" in err (JSON paths, files with their
 * line), -ENOMEM. Main thread, load time only.
 */
#ifndef COGW_APPS_PDO_CONFIG_H
#define COGW_APPS_PDO_CONFIG_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include <cjson/cJSON.h>

#include "apps/common/config.h"

/* Largest "types" list of one node. */
#define COGW_NODE_TYPES_MAX 1024u

/* The optional "pdo" of object o (path names it) into *mode, which holds
 * the default. */
int cogw_pdo_mode_parse(const cJSON *o, const char *path, uint8_t *mode, char *err, size_t errlen);

/* A node's "config" (cogw_node_config_parse), "eds", "types" and "pdo"
 * (default: the line's l->pdo) into n; np is the node's JSON path. */
int cogw_node_pdo_parse(const cJSON *node, const char *np, const cogw_line_config *l, cogw_node *n,
			const cogw_load *ld);
void cogw_node_pdo_free(cogw_node *n); /* what cogw_node_pdo_parse added */
/* The PDO settings and the file layouts agree (what a reload compares). */
bool cogw_node_pdo_equal(const cogw_node *a, const cogw_node *b);

/* A node whose layout is learnt by SDO needs the line's manager (the scan
 * is a step of its boot): the first such node is an error at its "pdo"
 * (or the line's). Call after the line's "manager" is parsed. */
int cogw_line_pdo_check(const cogw_line_config *l, const char *path, char *err, size_t errlen);

/* A node learns its layout by SDO scan during its boot. */
bool cogw_node_pdo_scanned(const cogw_node *n);
/* A node has a place in the line's table of layouts (core/pdo_layout.h):
 * it is scanned or has a file layout. */
bool cogw_node_pdo_kept(const cogw_node *n);

#endif /* COGW_APPS_PDO_CONFIG_H */
