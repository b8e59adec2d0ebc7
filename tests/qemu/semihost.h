/*
 * ARM semihosting for the emulated Cortex-M3 test image (qemu mps2-an385,
 * -semihosting-config enable=on,target=native). Output and exit status go to
 * the host through `bkpt 0xab`, and a test may read a small host file.
 */
#ifndef IT2N_SEMIHOST_H
#define IT2N_SEMIHOST_H

/* Write a NUL-terminated string to the host console (SYS_WRITE0). */
void it2n_sh_write0(const char *s);

/*
 * End the emulation with exit status `code` (SYS_EXIT_EXTENDED,
 * ADP_Stopped_ApplicationExit + subcode: qemu exits with `code`). Never
 * returns.
 */
void it2n_sh_exit(int code);

/*
 * Read up to len - 1 bytes of the host file `path` (relative to qemu's
 * working directory) into buf, NUL-terminated (SYS_OPEN, SYS_READ,
 * SYS_CLOSE). Returns the bytes read, or -1 when the file cannot be opened.
 * Test images only: the reboot test tells the firmware which measurement
 * to take this boot.
 */
int it2n_sh_read_file(const char *path, char *buf, unsigned len);

#endif /* IT2N_SEMIHOST_H */
