"""Case definitions: scenes for the validation problems."""
