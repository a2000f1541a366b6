"""Test helpers of the configuration's sections (fsi/config)."""



