/* SPDX-License-Identifier: MIT */
#include "lines/log.h"

#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <unistd.h>

#include "core/pdo_layout.h"

/* Process-wide settings written once at start-up by the main thread. */
static atomic_int use_prefix;
static atomic_int max_level = COGW_LOG_INFO;

void cogw_log_use_prefix(int on)
{
	atomic_store(&use_prefix, on);
}

void cogw_log_set_max_level(int level)
{
	atomic_store(&max_level, level);
}

static const char *level_word(int level)
{
	switch (level) {
	case COGW_LOG_ERR:
		return "error";
	case COGW_LOG_WARNING:
		return "warning";
	case COGW_LOG_NOTICE:
		return "notice";
	case COGW_LOG_INFO:
		return "info";
	default:
		return "debug";
	}
}

void cogw_log(int level, const char *fmt, ...)
{
	if (level > atomic_load(&max_level))
		return;
	char buf[1024];
	int n = atomic_load(&use_prefix)
			? snprintf(buf, sizeof buf, "<%d>", level)
			: snprintf(buf, sizeof buf, "cogwd: %s: ", level_word(level));
	va_list ap;
	va_start(ap, fmt);
	int m = vsnprintf(buf + n, sizeof buf - (size_t)n - 1, fmt, ap);
	va_end(ap);
	if (m < 0)
		return;
	size_t len = (size_t)n + ((size_t)m < sizeof buf - (size_t)n - 1
					  ? (size_t)m
					  : sizeof buf - (size_t)n - 2);
	buf[len++] = '\n';
	/* one write per line keeps lines from different threads whole */
	ssize_t w = write(STDERR_FILENO, buf, len);
	(void)w;
}

void cogw_log_pdo_layout(const char *line_name, const co_pdo_layout *t, uint8_t node_id)
{
	const co_pdo_layout_node *n = co_pdo_layout_node_get(t, node_id);
	char text[1024];

	if (!n)
		return;
	for (unsigned d = 0; d < 2; d++) {
		co_pdo_dir dir = d == 0 ? CO_PDO_TX : CO_PDO_RX;
		for (unsigned k = 0; k < n->n[dir]; k++) {
			co_pdo_layout_pdo_format(text, sizeof text, dir, &n->pdo[dir][k]);
			cogw_log(COGW_LOG_INFO, "line %s: node %u: PDO layout (%s): %s", line_name,
				 node_id, co_pdo_layout_source_to_string(n->source), text);
		}
	}
}
