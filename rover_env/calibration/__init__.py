"""Model-discrepancy workflow: replay measured drives, localise the gap, name the missing effect."""
