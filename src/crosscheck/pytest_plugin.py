"""pytest plugin that collects case files as tests (filled by the comparer/reports work)."""
