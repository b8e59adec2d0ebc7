/* porthint.c — see porthint.h. */
#include "porthint.h"

#include <dirent.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* The inode of the socket listening on port (state 0A), or 0. */
static unsigned long listen_inode(int port)
{
    static const char *const files[] = {"/proc/net/tcp", "/proc/net/tcp6"};
    for (size_t f = 0; f < sizeof files / sizeof files[0]; f++) {
        FILE *fp = fopen(files[f], "r");
        char line[512];
        if (!fp)
            continue;
        while (fgets(line, sizeof line, fp)) {
            char local[128], remote[128];
            unsigned st, lport;
            unsigned long inode;
            const char *colon;
            if (sscanf(line, " %*d: %127s %127s %x %*s %*s %*s %*s %*s %lu", local, remote, &st, &inode) != 4)
                continue;
            colon = strrchr(local, ':');
            if (!colon || sscanf(colon + 1, "%x", &lport) != 1)
                continue;
            if (st == 0x0A && (int)lport == port && inode) {
                fclose(fp);
                return inode;
            }
        }
        fclose(fp);
    }
    return 0;
}

void porthint_holder(int port, char *buf, size_t size)
{
    unsigned long inode = listen_inode(port);
    char want[64];
    DIR *proc;
    const struct dirent *e;
    buf[0] = 0;
    if (!inode)
        return;
    snprintf(want, sizeof want, "socket:[%lu]", inode);
    snprintf(buf, size, "another process (not visible to this user; try: ss -ltnp 'sport = :%d')", port);
    proc = opendir("/proc");
    if (!proc)
        return;
    while ((e = readdir(proc)) != NULL) {
        char path[300], link[64];
        DIR *fds;
        const struct dirent *fe;
        long pid = strtol(e->d_name, NULL, 10);
        if (pid <= 0)
            continue;
        snprintf(path, sizeof path, "/proc/%ld/fd", pid);
        fds = opendir(path);
        if (!fds)
            continue;
        while ((fe = readdir(fds)) != NULL) {
            ssize_t n;
            if (fe->d_name[0] == '.')
                continue;
            snprintf(path, sizeof path, "/proc/%ld/fd/%s", pid, fe->d_name);
            n = readlink(path, link, sizeof link - 1);
            if (n <= 0)
                continue;
            link[n] = 0;
            if (!strcmp(link, want)) {
                char comm[64] = "?";
                FILE *fp;
                snprintf(path, sizeof path, "/proc/%ld/comm", pid);
                fp = fopen(path, "r");
                if (fp) {
                    if (fgets(comm, sizeof comm, fp))
                        comm[strcspn(comm, "\n")] = 0;
                    fclose(fp);
                }
                snprintf(buf, size, "%s (pid %ld)", comm, pid);
                closedir(fds);
                closedir(proc);
                return;
            }
        }
        closedir(fds);
    }
    closedir(proc);
}

void porthint_in_use(const char *host, const char *port, const char *what_flag, char *buf, size_t size)
{
    char who[160];
    int v6 = strchr(host, ':') != NULL;
    porthint_holder(atoi(port), who, sizeof who);
    snprintf(buf, size, "%s%s%s:%s is in use%s%s; stop that process or choose another port (%s)", v6 ? "[" : "", host,
             v6 ? "]" : "", port, who[0] ? " by " : "", who, what_flag);
}
