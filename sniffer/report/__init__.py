"""The report command\x27s parts: what it gathers (collect), how it writes it (html, markdown)."""
