/* Internal: what mapstore.c shares with the other files of the map store. */
#ifndef SOOC3D_MAPSTORE_IMPL_H
#define SOOC3D_MAPSTORE_IMPL_H

#include <sqlite3.h>

#include "sooc3d/mapstore.h"

/* The store's connection, path, read-only flag and stored schema version. */
sqlite3 *sooc__mapstore_db(sooc_mapstore *s);
int sooc__mapstore_readonly(const sooc_mapstore *s);

/* Schema version 3 (mapstore_geom.c): the object geometry table and its
 * delete trigger; executed on creation and by the 2 -> 3 migration. */
extern const char *const sooc__mapstore_geom_schema;

#endif
