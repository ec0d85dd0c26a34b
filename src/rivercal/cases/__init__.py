"""Cases shipped with rivercal as package data (one folder per case)."""
