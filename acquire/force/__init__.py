"""Force sources: the testing machine's force signal (CSV, simulator, TCP, Modbus), read onto frame times."""
