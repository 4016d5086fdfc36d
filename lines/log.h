/* SPDX-License-Identifier: MIT */
/*
 * lines/log.h - the daemon's log lines (only apps/ and lines/ log).
 *
 * One line per message on stderr, with a sd-daemon "<N>" priority prefix so
 * journald files it at the right level when running under systemd, and
 * plain text with a level word otherwise. Thread-safe (one write(2) per
 * line); not for the per-frame path.
 */
#ifndef COGW_LINES_LOG_H
#define COGW_LINES_LOG_H

#include <stdint.h>

enum cogw_log_level {
	COGW_LOG_ERR = 3,
	COGW_LOG_WARNING = 4,
	COGW_LOG_NOTICE = 5,
	COGW_LOG_INFO = 6,
	COGW_LOG_DEBUG = 7,
};

/* Use the "<N>" prefix (set when JOURNAL_STREAM or NOTIFY_SOCKET is set). */
void cogw_log_use_prefix(int on);
void cogw_log_set_max_level(int level);
void cogw_log(int level, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* A node's learnt PDO layout (core/pdo_layout.h), one INFO line per PDO:
 * "line line0: node 5: PDO layout (scan): TPDO 1 COB-ID 185h tt 254 ...". */
struct co_pdo_layout;
void cogw_log_pdo_layout(const char *line_name, const struct co_pdo_layout *t, uint8_t node_id);

#endif /* COGW_LINES_LOG_H */
