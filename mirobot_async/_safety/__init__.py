"""Private: safety modules of mirobot_async (import from the package root)."""
