/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-mqtt/main.c - cogw-mqtt: the MQTT bridge of a cogw gateway
 * (docs/mqtt.md). A mailbox client of cogwd like any other: it never
 * touches CAN, and a broker that is slow or away only fills its own
 * bounded queue.
 *
 *   cogw-mqtt [--config FILE] [--daemon-config FILE] [--check] [-v]
 */
#include "apps/cogw-mqtt/bridge.h"
#include "apps/common/mbx_loop.h"
#include "apps/common/signal_loop.h"
#include "apps/common/version.h"
#include "apps/cogw-mqtt/mqtt_watch.h"

#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/signalfd.h>
#include <systemd/sd-daemon.h>
#include <time.h>
#include <unistd.h>

#define EPOLL_TAG_SIGNAL 0u
#define EPOLL_TAG_MAILBOX 1u
/* the bridge's own mailbox requests under way at once: node table,
 * mailbox and gateway counters of every line, boot diagnostics of nodes */
#define INTERNAL_SLOTS(n_lines) (8u * (n_lines) + 8u)

static void usage(FILE *f)
{
	fprintf(f, "usage: cogw-mqtt [--config FILE] [--daemon-config FILE] [--check] [-v]\n"
		   "  --config FILE         the bridge's configuration (docs/mqtt.md)\n"
		   "  --daemon-config FILE  cogwd's configuration (instance, networks; default:\n"
		   "                        the configuration's daemon_config, else cogwd's\n"
		   "                        embedded default)\n"
		   "  --check               validate both configurations and exit\n"
		   "  -v                    log refusals and reconnects (-v -v: libmosquitto)\n");
}

typedef struct cli {
	const char *config, *daemon_config;
	bool check;
} cli;

static int parse_args(bridge *b, cli *c, int argc, char **argv)
{
	for (int i = 1; i < argc; i++) {
		const char *a = argv[i];

		if (strcmp(a, "--config") == 0 && i + 1 < argc) {
			c->config = argv[++i];
		} else if (strcmp(a, "--daemon-config") == 0 && i + 1 < argc) {
			c->daemon_config = argv[++i];
		} else if (strcmp(a, "--check") == 0) {
			c->check = true;
		} else if (strcmp(a, "-v") == 0) {
			b->verbose++;
		} else if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
			usage(stdout);
			return 0;
		} else {
			fprintf(stderr, "cogw-mqtt: unknown argument '%s'\n", a);
			usage(stderr);
			return 2;
		}
	}
	return -1;
}

static int load_configs(bridge *b, const cli *c)
{
	char err[600];
	int rc;

	if (mqtt_config_load_file(&b->cfg, c->config, err, sizeof err)) {
		fprintf(stderr, "cogw-mqtt: %s\n", err);
		return -1;
	}
	snprintf(b->daemon_config_path, sizeof b->daemon_config_path, "%s",
		 c->daemon_config ? c->daemon_config : b->cfg.daemon_config);
	rc = b->daemon_config_path[0]
		     ? cogw_config_load_file(&b->daemon, b->daemon_config_path, err, sizeof err)
		     : cogw_config_load_string(&b->daemon, cogw_default_config_json,
					       COGW_DEFAULT_CONFIG_SOURCE, err, sizeof err);
	if (rc) {
		fprintf(stderr, "cogw-mqtt: daemon configuration: %s\n", err);
		return -1;
	}
	if (b->cfg.route_line >= b->daemon.n_lines) {
		fprintf(stderr, "cogw-mqtt: route_line %u: the daemon has %zu line(s)\n",
			b->cfg.route_line, b->daemon.n_lines);
		return -1;
	}
	return 0;
}

static int open_signals(bridge *b)
{
	return signal_loop_open("cogw-mqtt", &b->sigfd, &b->epfd);
}

static int open_loop(bridge *b)
{
	struct epoll_event ev = { .events = EPOLLIN };

	ev.data.u32 = EPOLL_TAG_SIGNAL;
	if (epoll_ctl(b->epfd, EPOLL_CTL_ADD, b->sigfd, &ev) < 0)
		return -1;
	ev.data.u32 = EPOLL_TAG_MAILBOX;
	return epoll_ctl(b->epfd, EPOLL_CTL_ADD, cogw_loop_fd(b->h), &ev);
}

static void drain_mailbox(bridge *b)
{
	cogw_msg m;

	/* all that waits: events come in bursts (a watched value per TPDO) and
	 * every turn of the loop services the broker link too */
	while (cogw_loop_recv(b->h, &m) == 0) {
		if (m.kind == MBX_KIND_EVENT) {
			events_on_event(b, &m);
		} else {
			pending *p = bridge_pending_of(b, m.corr);

			if (p && p->internal) {
				unsigned line = p->line;

				events_on_internal(b, p, &m);
				bridge_pending_release(p);
				/* the freed slot takes the next configured watch */
				mqtt_watch_arm_rest(b, line);
			} else if (p) {
				serve_on_response(b, p, &m);
			}
		}
		cogw_msg_release(&m);
	}
}

static int run(bridge *b)
{
	struct epoll_event evs[8];

	while (!b->stopping) {
		uint32_t mqtt_ev = 0;
		uint64_t now = bridge_now_ms(), next = link_next_deadline(b);
		int timeout = next <= now ? 0 : next - now > 200 ? 200 : (int)(next - now);

		link_sync_epoll(b);
		int n = epoll_wait(b->epfd, evs, 8, mbx_loop_wait_ms(b->h, timeout));

		if (n < 0 && errno != EINTR) {
			perror("cogw-mqtt: epoll_wait");
			return -1;
		}
		/* leases, a daemon restart, requests past libcogw's time-out */
		cogw_loop_tick(b->h);
		for (int i = 0; i < n; i++) {
			if (evs[i].data.u32 == EPOLL_TAG_SIGNAL) {
				struct signalfd_siginfo si;

				while (read(b->sigfd, &si, sizeof si) == sizeof si)
					if (si.ssi_signo != SIGHUP)
						b->stopping = true;
			} else if (evs[i].data.u32 == EPOLL_TAG_MAILBOX) {
				drain_mailbox(b);
			} else {
				mqtt_ev |= evs[i].events;
			}
		}
		if (b->stopping)
			break;
		link_service(b, mqtt_ev);
		events_service(b);
		serve_expire(b);
	}
	return 0;
}

static void print_totals(const bridge *b)
{
	const bridge_stats *s = &b->st;

	fprintf(stderr,
		"cogw-mqtt: stopping: %llu published, %llu queued, %llu dropped (queue full), "
		"%llu connects, %llu connect failures, %llu disconnects, %llu events (%llu lost "
		"in the mailbox), %llu requests (%llu ok, %llu refused role, %llu malformed, "
		"%llu too big, %llu bad field, %llu unknown op, %llu rate limited, %llu busy, "
		"%llu unsupported, %llu failed, %llu timed out)\n",
		(unsigned long long)s->published, (unsigned long long)s->queued,
		(unsigned long long)s->dropped, (unsigned long long)s->connects,
		(unsigned long long)s->connect_failures, (unsigned long long)s->disconnects,
		(unsigned long long)s->events, (unsigned long long)s->events_lost,
		(unsigned long long)s->requests, (unsigned long long)s->replies_ok,
		(unsigned long long)s->refused_role, (unsigned long long)s->malformed,
		(unsigned long long)s->too_big, (unsigned long long)s->bad_field,
		(unsigned long long)s->unknown_op, (unsigned long long)s->rate_limited,
		(unsigned long long)s->busy, (unsigned long long)s->unsupported,
		(unsigned long long)s->failed, (unsigned long long)s->timed_out);
}

int main(int argc, char **argv)
{
	static bridge b;
	cli c = { 0 };
	if (cogw_version_asked("cogw-mqtt", argc, argv))
		return 0;
	int rc = parse_args(&b, &c, argc, argv);

	if (rc >= 0)
		return rc;
	if (load_configs(&b, &c))
		return 1;
	if (c.check) {
		printf("cogw-mqtt: configuration OK (gateway %s, broker %s:%u, role %s, instance "
		       "%s, %zu line(s))\n",
		       b.cfg.gateway, b.cfg.host, b.cfg.port, mqtt_role_to_string(b.cfg.role),
		       b.daemon.mailbox.instance, b.daemon.n_lines);
		cogw_config_free(&b.daemon);
		return 0;
	}
	b.nodes = calloc(b.daemon.n_lines * 128u, sizeof *b.nodes);
	b.n_pend = b.cfg.max_inflight + INTERNAL_SLOTS(b.daemon.n_lines);
	b.pend = calloc(b.n_pend, sizeof *b.pend);
	if (!b.nodes || !b.pend) {
		fprintf(stderr, "cogw-mqtt: out of memory\n");
		return 1;
	}
	for (size_t i = 0; i < b.daemon.n_lines * 128u; i++)
		b.nodes[i].nmt = 0xFF;
	b.tokens = b.cfg.requests_per_s;
	b.tokens_ms = bridge_now_ms();
	if (open_signals(&b))
		return 1;
	cogw_options o = { .instance = b.daemon.mailbox.instance,
			   .timeout_ms = 2000,
			   .resp_depth = 64,
			   .event_depth = 64 };
	rc = mbx_loop_open(&b.h, &o, b.daemon.n_lines, "cogw-mqtt");
	if (rc < 0) {
		fprintf(stderr, "cogw-mqtt: mailbox of instance %s: %s\n", o.instance,
			cogw_strerror(rc));
		return 1;
	}
	/* the broker link calls up through these */
	const link_hooks up = { .on_connect = events_on_connect, .on_message = serve_on_message };
	if (open_loop(&b) || link_init(&b, &up)) {
		cogw_close(b.h);
		return 1;
	}
	sd_notify(0, "READY=1");
	fprintf(stderr,
		"cogw-mqtt: bridging instance %s (%zu line(s)) to %s:%u as gateway %s, role %s\n",
		o.instance, b.daemon.n_lines, b.cfg.host, b.cfg.port, b.cfg.gateway,
		mqtt_role_to_string(b.cfg.role));
	rc = run(&b);
	sd_notify(0, "STOPPING=1");
	link_stop(&b);
	print_totals(&b);
	for (size_t i = 0; i < b.n_pend; i++)
		bridge_pending_release(&b.pend[i]);
	link_free(&b);
	cogw_close(b.h);
	events_free(&b);
	free(b.pend);
	close(b.epfd);
	close(b.sigfd);
	cogw_config_free(&b.daemon);
	return rc < 0 ? 1 : 0;
}
