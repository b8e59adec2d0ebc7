# cli/: the host command-line tool `it2n` (owned by the CLI work).
