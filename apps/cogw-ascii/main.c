/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-ascii/main.c - cogw-ascii: CiA 309-3 ASCII commands over UNIX
 * and TCP stream sockets, carried out through cogwd's mailbox (a client
 * process like any other: it never touches CAN). docs/ascii.md.
 *
 *   cogw-ascii [--config FILE] [--daemon-config FILE] [--socket PATH]
 *              [--check] [-v]
 *
 * Listeners come from systemd socket activation (sd_listen_fds: every
 * stream socket passed; an AF_INET/AF_INET6 one is a TCP listener) or are
 * bound here from the configuration.
 */
#include "apps/cogw-ascii/gateway.h"
#include "apps/common/mbx_loop.h"
#include "apps/common/signal_loop.h"
#include "apps/common/version.h"

#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/signalfd.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <systemd/sd-daemon.h>
#include <unistd.h>

static void usage(FILE *f)
{
	fprintf(f, "usage: cogw-ascii [--config FILE] [--daemon-config FILE] [--socket PATH]\n"
		   "                  [--check] [-v]\n"
		   "  --config FILE         the gateway's configuration (docs/ascii.md)\n"
		   "  --daemon-config FILE  cogwd's configuration (instance, networks, access\n"
		   "                        rules; default: the configuration's daemon_config,\n"
		   "                        else cogwd's embedded default)\n"
		   "  --socket PATH         the UNIX socket (overrides unix_socket; \"\" = none)\n"
		   "  --check               validate both configurations and exit\n"
		   "  -v                    log connections to stderr\n");
}

static int bind_unix(gateway *g, const char *path)
{
	struct sockaddr_un a = { .sun_family = AF_UNIX };
	struct stat st;
	int fd;

	if (strlen(path) >= sizeof a.sun_path) {
		fprintf(stderr, "cogw-ascii: %s: socket path too long\n", path);
		return -1;
	}
	strcpy(a.sun_path, path);
	/* a socket file left by an earlier run; anything else is not ours */
	if (lstat(path, &st) == 0) {
		if (!S_ISSOCK(st.st_mode)) {
			fprintf(stderr, "cogw-ascii: %s exists and is not a socket\n", path);
			return -1;
		}
		unlink(path);
	}
	fd = socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
	if (fd < 0 || bind(fd, (struct sockaddr *)&a, sizeof a) < 0 ||
	    chmod(path, g->cfg.unix_mode) < 0 || listen(fd, 128) < 0) {
		fprintf(stderr, "cogw-ascii: %s: %s\n", path, strerror(errno));
		if (fd >= 0)
			close(fd);
		return -1;
	}
	g->listen_fd[g->n_listen] = fd;
	g->listen_tcp[g->n_listen++] = false;
	return 0;
}

static int bind_tcp(gateway *g)
{
	struct sockaddr_storage ss = { 0 };
	socklen_t len;
	int one = 1, fd;
	struct sockaddr_in *a4 = (struct sockaddr_in *)&ss;
	struct sockaddr_in6 *a6 = (struct sockaddr_in6 *)&ss;

	if (inet_pton(AF_INET, g->cfg.tcp_address, &a4->sin_addr) == 1) {
		a4->sin_family = AF_INET;
		a4->sin_port = htons(g->cfg.tcp_port);
		len = sizeof *a4;
	} else if (inet_pton(AF_INET6, g->cfg.tcp_address, &a6->sin6_addr) == 1) {
		a6->sin6_family = AF_INET6;
		a6->sin6_port = htons(g->cfg.tcp_port);
		len = sizeof *a6;
	} else {
		return -1; /* the loader checked it */
	}
	fd = socket(ss.ss_family, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
	if (fd < 0 || setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one) < 0 ||
	    bind(fd, (struct sockaddr *)&ss, len) < 0 || listen(fd, 128) < 0) {
		fprintf(stderr, "cogw-ascii: tcp %s port %u: %s\n", g->cfg.tcp_address,
			g->cfg.tcp_port, strerror(errno));
		if (fd >= 0)
			close(fd);
		return -1;
	}
	g->listen_fd[g->n_listen] = fd;
	g->listen_tcp[g->n_listen++] = true;
	return 0;
}

/* Socket activation: the stream sockets systemd passes. */
static int take_activated(gateway *g)
{
	int n = sd_listen_fds(1);

	for (int i = 0; i < n && g->n_listen < 8; i++) {
		int fd = SD_LISTEN_FDS_START + i;
		struct sockaddr_storage ss;
		socklen_t len = sizeof ss;

		if (sd_is_socket(fd, AF_UNSPEC, SOCK_STREAM, 1) <= 0 ||
		    getsockname(fd, (struct sockaddr *)&ss, &len) < 0) {
			fprintf(stderr,
				"cogw-ascii: passed descriptor %d is not a listening "
				"stream socket\n",
				fd);
			return -1;
		}
		g->listen_fd[g->n_listen] = fd;
		g->listen_tcp[g->n_listen++] = ss.ss_family == AF_INET || ss.ss_family == AF_INET6;
	}
	return n < 0 ? -1 : n;
}

static int load_daemon_config(gateway *g, const char *path)
{
	char err[512];
	int rc = path && *path
			 ? cogw_config_load_file(&g->daemon, path, err, sizeof err)
			 : cogw_config_load_string(&g->daemon, cogw_default_config_json,
						   COGW_DEFAULT_CONFIG_SOURCE, err, sizeof err);

	if (rc)
		fprintf(stderr, "cogw-ascii: daemon configuration: %s\n", err);
	return rc;
}

/* The command line. */
typedef struct cli {
	const char *config, *daemon_config, *socket_path;
	bool check;
} cli;

/* Returns -1 to go on, else the exit status (--help, a bad argument). */
static int parse_args(gateway *g, cli *c, int argc, char **argv)
{
	for (int i = 1; i < argc; i++) {
		const char *a = argv[i];

		if ((strcmp(a, "--config") == 0 || strcmp(a, "--daemon-config") == 0 ||
		     strcmp(a, "--socket") == 0) &&
		    i + 1 < argc) {
			const char **dst = a[2] == 'c'   ? &c->config
					   : a[2] == 'd' ? &c->daemon_config
							 : &c->socket_path;
			*dst = argv[++i];
		} else if (strcmp(a, "--check") == 0) {
			c->check = true;
		} else if (strcmp(a, "-v") == 0) {
			g->verbose++;
		} else if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
			usage(stdout);
			return 0;
		} else {
			fprintf(stderr, "cogw-ascii: unknown argument '%s'\n", a);
			usage(stderr);
			return 2;
		}
	}
	return -1;
}

/* The gateway's configuration, then the daemon's it names (or the one
 * given), checked against each other. */
static int load_configs(gateway *g, const cli *c)
{
	char err[512];

	if (ascii_config_load_file(&g->cfg, c->config, err, sizeof err)) {
		fprintf(stderr, "cogw-ascii: %s\n", err);
		return -1;
	}
	if (c->socket_path)
		snprintf(g->cfg.unix_socket, sizeof g->cfg.unix_socket, "%s", c->socket_path);
	snprintf(g->daemon_config_path, sizeof g->daemon_config_path, "%s",
		 c->daemon_config ? c->daemon_config : g->cfg.daemon_config);
	if (load_daemon_config(g, g->daemon_config_path))
		return -1;
	if (g->cfg.route_line >= g->daemon.n_lines) {
		fprintf(stderr, "cogw-ascii: route_line %u: the daemon has %zu line(s)\n",
			g->cfg.route_line, g->daemon.n_lines);
		return -1;
	}
	if (g->cfg.default_network < 0)
		g->cfg.default_network = g->daemon.lines[0].network_id;
	return 0;
}

static int open_signals(gateway *g)
{
	return signal_loop_open("cogw-ascii", &g->sigfd, &g->epfd);
}

/* Returns how many listeners systemd passed (0: bound here), or -1. */
static int open_listeners(gateway *g)
{
	int activated = take_activated(g);

	if (activated < 0)
		return -1;
	if (activated == 0) {
		if (g->cfg.unix_socket[0] && bind_unix(g, g->cfg.unix_socket) < 0)
			return -1;
		if (g->cfg.tcp && bind_tcp(g) < 0)
			return -1;
	}
	if (g->n_listen == 0) {
		fprintf(stderr, "cogw-ascii: nothing to listen on (no unix_socket, no tcp, "
				"no socket passed by systemd)\n");
		return -1;
	}
	return activated;
}

static void print_totals(const gateway *g)
{
	fprintf(stderr,
		"cogw-ascii: stopping: %llu connections (%llu refused full, %llu refused access), "
		"%llu commands, %llu syntax errors, %llu denied, %llu overlong lines, %llu slow "
		"readers, %llu mailbox errors, %llu requests given up\n",
		(unsigned long long)g->st.accepted, (unsigned long long)g->st.refused_full,
		(unsigned long long)g->st.refused_access, (unsigned long long)g->st.commands,
		(unsigned long long)g->st.syntax_errors, (unsigned long long)g->st.denied,
		(unsigned long long)g->st.overlong, (unsigned long long)g->st.slow_readers,
		(unsigned long long)g->st.mbx_errors, (unsigned long long)g->st.expired);
}

int main(int argc, char **argv)
{
	static gateway g;
	cli c = { 0 };
	int activated;
	if (cogw_version_asked("cogw-ascii", argc, argv))
		return 0;
	int rc = parse_args(&g, &c, argc, argv);

	if (rc >= 0)
		return rc;
	if (load_configs(&g, &c))
		return 1;
	if (c.check) {
		printf("cogw-ascii: configuration OK (instance %s, %zu line(s))\n",
		       g.daemon.mailbox.instance, g.daemon.n_lines);
		cogw_config_free(&g.daemon);
		return 0;
	}
	/* one less than the daemon's per-client limit: the subscriptions'
	 * requests must never make a command's request BUSY */
	g.inflight_max = g.daemon.mailbox.max_outstanding ? g.daemon.mailbox.max_outstanding : 16;
	if (g.inflight_max > 1)
		g.inflight_max--;
	if (open_signals(&g))
		return 1;
	activated = open_listeners(&g);
	if (activated < 0)
		return 1;
	/* deep queues: the answers of many connections' transfers share them */
	cogw_options o = { .instance = g.daemon.mailbox.instance,
			   .timeout_ms = 2000,
			   .resp_depth = GW_RESP_DEPTH,
			   .event_depth = 64 };
	rc = mbx_loop_open(&g.h, &o, g.daemon.n_lines, "cogw-ascii");
	if (rc < 0) {
		fprintf(stderr, "cogw-ascii: mailbox of instance %s: %s\n", o.instance,
			cogw_strerror(rc));
		return 1;
	}
	sd_notify(0, "READY=1");
	fprintf(stderr, "cogw-ascii: serving instance %s (%zu line(s)) on %u listener(s)\n",
		o.instance, g.daemon.n_lines, g.n_listen);
	rc = server_run(&g);
	sd_notify(0, "STOPPING=1");
	print_totals(&g);
	cogw_close(g.h);
	if (activated == 0 && g.cfg.unix_socket[0])
		unlink(g.cfg.unix_socket);
	for (unsigned i = 0; i < g.n_listen; i++)
		close(g.listen_fd[i]);
	free(g.sent);
	cogw_config_free(&g.daemon);
	return rc < 0 ? 1 : 0;
}
