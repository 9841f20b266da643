"""Checking a space: the rule engine (loading, configuring, running rules), anchoring findings
at manifest lines, and printing them (text, JSON, SARIF, GitHub). Rules themselves live in rules/."""
