"""Private: client modules of mirobot_async (import from the package root)."""
